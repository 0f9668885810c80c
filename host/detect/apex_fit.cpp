#include "dentmark/host/detect/apex_fit.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

#include "dentmark/common/nth_smallest.h"

namespace dentmark::detect {

namespace {

// Which cells of kCell x kCell pixels hold a selected pixel, summed as an integral image:
// whether a rectangle of pixels touches one is two lookups.
class SelectedCells {
 public:
  SelectedCells() = default;
  SelectedCells(const std::vector<std::uint8_t>& select, int rows, int cols)
      : rows_(rows),
        cols_(cols),
        cell_rows_((rows + kCell - 1) / kCell),
        cell_cols_((cols + kCell - 1) / kCell) {
    const auto stride = static_cast<std::size_t>(cell_cols_ + 1);
    sum_.assign(stride * static_cast<std::size_t>(cell_rows_ + 1), 0);
#pragma omp parallel for schedule(static)
    for (int cr = 0; cr < cell_rows_; ++cr)  // (a row of cells a thread)
      for (int r = cr * kCell; r < std::min(rows, (cr + 1) * kCell); ++r)
        for (int c = 0; c < cols; ++c)
          if (select[static_cast<std::size_t>(r) * cols + c])
            sum_[static_cast<std::size_t>(cr + 1) * stride + c / kCell + 1] = 1;
    for (int r = 1; r <= cell_rows_; ++r)
      for (int c = 1; c <= cell_cols_; ++c)
        sum_[r * stride + c] +=
            sum_[(r - 1) * stride + c] + sum_[r * stride + c - 1] - sum_[(r - 1) * stride + c - 1];
  }
  // Whether pixels [r0, r1] x [c0, c1] (any values; clamped to the map) hold a selected one.
  bool any(float r0, float c0, float r1, float c1) const {
    if (!(r1 >= 0.0f && c1 >= 0.0f && r0 < static_cast<float>(rows_) && c0 < static_cast<float>(cols_)))
      return false;  // off the map
    const int a = static_cast<int>(std::max(r0, 0.0f)) / kCell,
              b = static_cast<int>(std::max(c0, 0.0f)) / kCell;
    const int e =
        std::min(static_cast<int>(std::min(r1, static_cast<float>(rows_ - 1))) / kCell, cell_rows_ - 1);
    const int f =
        std::min(static_cast<int>(std::min(c1, static_cast<float>(cols_ - 1))) / kCell, cell_cols_ - 1);
    const auto stride = static_cast<std::size_t>(cell_cols_ + 1);
    return sum_[(e + 1) * stride + f + 1] - sum_[a * stride + f + 1] - sum_[(e + 1) * stride + b] +
               sum_[a * stride + b] >
           0;
  }

 private:
  static constexpr int kCell = 8;
  int rows_ = 0, cols_ = 0, cell_rows_ = 0, cell_cols_ = 0;
  std::vector<std::int32_t> sum_;
};

}  // namespace

PixelSamples::PixelSamples(const ingest::MeshView& mesh, const HeightMap& map,
                           const std::vector<std::uint8_t>& select) {
  // (pixel << 32 | vertex, point): sorted, the points of a pixel in vertex order
  // whatever order the threads' finds were merged in (the same result every run).
  std::vector<std::pair<std::uint64_t, Eigen::Vector3f>> found;
  const Eigen::Matrix3f axes = map.axes.cast<float>();
  const Eigen::Vector3f origin = map.origin.cast<float>();
  // Pixel of a point as HeightMap::pixel_of, in floats (map coordinates within metres of
  // the origin: 0.1 µm), multiplied by the inverse: a streaming pass over every vertex.
  const auto u0 = static_cast<float>(map.u0), v0 = static_cast<float>(map.v0);
  const auto inv = static_cast<float>(1.0 / map.pixel);
  const auto cols = static_cast<float>(map.cols), rows = static_cast<float>(map.rows);
  const auto n = static_cast<std::int64_t>(mesh.vertex_count());
  // In blocks: the pixels of a block's vertices in a loop without branches (-1 off the
  // map), then the few selected ones picked out.
  constexpr auto kBlock = static_cast<std::int64_t>(ingest::VertexBlocks::kSize);
  const std::int32_t map_cols = map.cols;
  const std::int64_t blocks = (n + kBlock - 1) / kBlock;
  // Where the view knows its blocks' boxes, a block whose box misses every selected
  // pixel is skipped: in sensor order a block is a short strip of the panel, and the
  // candidates cover a few per cent of it (the pass read every vertex: 7-12 ms).
  const ingest::VertexBlocks* boxes = mesh.vertex_blocks();
  if (boxes && boxes->lo.size() != static_cast<std::size_t>(blocks)) boxes = nullptr;
  const SelectedCells cells = boxes ? SelectedCells(select, map.rows, map.cols) : SelectedCells();
  const auto selects_any = [&](std::int64_t blk) {
    const Eigen::Vector3f &lo = boxes->lo[static_cast<std::size_t>(blk)],
                          &hi = boxes->hi[static_cast<std::size_t>(blk)];
    // The box's corners in pixels, as the vertices' are computed below; a vertex's lies
    // between them (a linear map), widened by a pixel for rounding.
    float c0 = std::numeric_limits<float>::infinity(), c1 = -c0, r0 = c0, r1 = -c0;
    for (int k = 0; k < 8; ++k) {
      const float px = (k & 1 ? hi.x() : lo.x()) - origin.x(), py = (k & 2 ? hi.y() : lo.y()) - origin.y(),
                  pz = (k & 4 ? hi.z() : lo.z()) - origin.z();
      const float c = (axes(0, 0) * px + axes(0, 1) * py + axes(0, 2) * pz - u0) * inv,
                  r = (axes(1, 0) * px + axes(1, 1) * py + axes(1, 2) * pz - v0) * inv;
      c0 = std::min(c0, c), c1 = std::max(c1, c), r0 = std::min(r0, r), r1 = std::max(r1, r);
    }
    return cells.any(std::floor(r0) - 1.0f, std::floor(c0) - 1.0f, std::floor(r1) + 1.0f,
                     std::floor(c1) + 1.0f);
  };
#pragma omp parallel
  {
    std::vector<std::pair<std::uint64_t, Eigen::Vector3f>> mine;
    std::int32_t pixel[kBlock];
    float x[kBlock], y[kBlock], z[kBlock];
    // (Dynamic: the blocks not skipped cluster where the candidates are.)
#pragma omp for schedule(dynamic, 64) nowait
    for (std::int64_t blk = 0; blk < blocks; ++blk) {
      if (boxes && !selects_any(blk)) continue;
      const std::int64_t first = blk * kBlock, m = std::min(kBlock, n - first);
      for (std::int64_t j = 0; j < m; ++j) {  // the loads apart: then the arithmetic vectorises
        const Eigen::Vector3f p = mesh.vertex(static_cast<std::size_t>(first + j));
        x[j] = p.x(), y[j] = p.y(), z[j] = p.z();
      }
#pragma omp simd
      for (std::int64_t j = 0; j < m; ++j) {
        const float px = x[j] - origin.x(), py = y[j] - origin.y(), pz = z[j] - origin.z();
        const float c = (axes(0, 0) * px + axes(0, 1) * py + axes(0, 2) * pz - u0) * inv,
                    r = (axes(1, 0) * px + axes(1, 1) * py + axes(1, 2) * pz - v0) * inv;
        const bool on = (c >= 0.0f) & (r >= 0.0f) & (c < cols) & (r < rows);  // also not NaN
        const auto ci = static_cast<std::int32_t>(on ? c : 0.0f),
                   ri = static_cast<std::int32_t>(on ? r : 0.0f);
        pixel[j] = on ? ri * map_cols + ci : -1;
      }
      for (std::int64_t j = 0; j < m; ++j)
        if (pixel[j] >= 0 && select[static_cast<std::size_t>(pixel[j])])
          mine.emplace_back(std::uint64_t{static_cast<std::uint32_t>(pixel[j])} << 32 |
                                static_cast<std::uint32_t>(first + j),
                            axes * (Eigen::Vector3f(x[j], y[j], z[j]) - origin));
    }
#pragma omp critical
    found.insert(found.end(), mine.begin(), mine.end());
  }
  std::sort(found.begin(), found.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  keys_.reserve(found.size());
  points_.reserve(found.size());
  for (const auto& [k, q] : found) keys_.push_back(static_cast<std::int32_t>(k >> 32)), points_.push_back(q);
}

void PixelSamples::append(std::int32_t pixel, std::vector<Eigen::Vector3d>& out) const {
  const auto range = std::equal_range(keys_.begin(), keys_.end(), pixel);
  for (auto it = range.first; it != range.second; ++it)
    out.push_back(points_[static_cast<std::size_t>(it - keys_.begin())].cast<double>());
}

namespace {

using Vector5d = Eigen::Matrix<double, 5, 1>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

Vector5d basis(double x, double y) {
  const double r2 = x * x + y * y;
  Vector5d b;
  b << 1, x, y, r2, r2 * r2;
  return b;
}

// With a term in r: a cone's tip.
Vector6d cone_basis(double x, double y) {
  const double r2 = x * x + y * y;
  Vector6d b;
  b << 1, x, y, std::sqrt(r2), r2, r2 * r2;
  return b;
}

// The least-squares coefficients of the samples' deviation (z) over basis(x, y), or
// nothing where the samples cannot settle them.
template <int K, typename Basis>
std::optional<Eigen::Matrix<double, K, 1>> least_squares(const std::vector<Eigen::Vector3d>& use,
                                                         Basis basis) {
  using Vector = Eigen::Matrix<double, K, 1>;
  using Matrix = Eigen::Matrix<double, K, K>;
  Matrix N = Matrix::Zero();
  Vector rhs = Vector::Zero();
  for (const auto& q : use) {
    const Vector b = basis(q.x(), q.y());
    N.template selfadjointView<Eigen::Lower>().rankUpdate(b);
    rhs += q.z() * b;
  }
  N.template triangularView<Eigen::Upper>() = N.transpose();
  const Eigen::LDLT<Matrix> ldlt(N);
  if (ldlt.info() != Eigen::Success || ldlt.vectorD().minCoeff() <= 1e-9 * N(0, 0)) return std::nullopt;
  const Vector p = ldlt.solve(rhs);
  if (!p.allFinite()) return std::nullopt;
  return p;
}

}  // namespace

namespace {

struct ApexFit {
  double x, y;  // the model's extreme (scaled by the radius), within half of it
  double value;
};

// One robust fit around (cx, cy) (m).
std::optional<ApexFit> fit_at(const std::vector<ApexSample>& samples, double cx, double cy, double radius,
                              double sign, bool round_window) {
  constexpr std::size_t kMinSamples = 12;
  constexpr double kRound = 1.5;     // largest / smallest spread of a round apex
  std::vector<Eigen::Vector3d> use;  // x, y scaled to the radius; deviation
  for (const auto& s : samples) {
    const double x = (s.x - cx) / radius, y = (s.y - cy) / radius;
    if (x * x + y * y <= 1.0 && std::isfinite(s.deviation)) use.emplace_back(x, y, s.deviation);
  }
  if (use.size() < kMinSamples) return std::nullopt;
  {
    // Gross outliers (millimetres off) would steer the first least-squares fit: drop
    // values far outside the spread of the disc's values first.
    std::vector<double> v;
    for (const auto& q : use) v.push_back(q.z());
    const double med = median_of(v);
    for (auto& x : v) x = std::abs(x - med);
    const double limit = 6.0 * kMadToSigma * median_of(v);
    std::erase_if(use, [&](const Eigen::Vector3d& q) { return std::abs(q.z() - med) > limit; });
  }
  Vector5d p = Vector5d::Zero();
  for (int pass = 0; pass < 4; ++pass) {
    if (use.size() < kMinSamples) return std::nullopt;
    const auto fitted = least_squares<5>(use, basis);
    if (!fitted) return std::nullopt;
    p = *fitted;
    if (pass == 3) break;
    // Drop residuals beyond 4 robust sigmas of the fit.
    std::vector<double> res;
    res.reserve(use.size());
    for (const auto& q : use) res.push_back(std::abs(q.z() - basis(q.x(), q.y()).dot(p)));
    const double limit = 4.0 * kMadToSigma * median_of(res);
    std::vector<Eigen::Vector3d> kept;
    for (std::size_t j = 0; j < use.size(); ++j)
      if (res[j] <= limit) kept.push_back(use[j]);
    if (kept.size() == use.size()) break;
    use.swap(kept);
  }
  // A sharp ding's tip is a cone's, which no polynomial in r² follows: its apex was read
  // 10-14 % short. Where a term in r fits clearly better (an F test on the same samples,
  // far beyond what noise gives a smooth apex), the model takes it.
  Vector6d cone = Vector6d::Zero();
  bool sharp = false;
  // Round ones only: a crease-shaped trough's cross-section is no cone (and read 25 %
  // deep with one). Round: the deviation-weighted spread of the samples alike both ways.
  Eigen::Matrix2d spread = Eigen::Matrix2d::Zero();
  for (const auto& q : use) spread += std::abs(q.z()) * q.head<2>() * q.head<2>().transpose();
  const Eigen::Vector2d axes = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(spread).eigenvalues();
  if (round_window && use.size() >= 2 * kMinSamples && axes(1) < kRound * axes(0))
    if (const auto fitted = least_squares<6>(use, cone_basis)) {
      cone = *fitted;
      double smooth_rss = 0.0, cone_rss = 0.0;
      for (const auto& q : use) {
        smooth_rss += std::pow(q.z() - basis(q.x(), q.y()).dot(p), 2);
        cone_rss += std::pow(q.z() - cone_basis(q.x(), q.y()).dot(cone), 2);
      }
      constexpr double kF = 25.0;  // F(1, n) beyond 25: p < 1e-5
      sharp = (smooth_rss - cone_rss) * static_cast<double>(use.size() - 6) > kF * std::max(cone_rss, 1e-30);
    }
  const auto model = [&](double x, double y) {
    return sharp ? cone_basis(x, y).dot(cone) : basis(x, y).dot(p);
  };
  // The model's extreme on a grid over the inner half of the disc.
  ApexFit f{0.0, 0.0, model(0.0, 0.0)};
  constexpr int kSteps = 10;
  for (int i = -kSteps; i <= kSteps; ++i)
    for (int j = -kSteps; j <= kSteps; ++j) {
      const double x = 0.5 * i / kSteps, y = 0.5 * j / kSteps;
      if (x * x + y * y > 0.25) continue;
      const double v = model(x, y);
      if (sign * v > sign * f.value) f.value = v, f.x = x, f.y = y;
    }
  return f;
}

// The fit over the disc of 'radius', re-centred (fit_apex_height in the header).
std::optional<double> fit_apex(const std::vector<ApexSample>& samples, double radius, double sign,
                               bool round_window) {
  if (!(radius > 0.0)) return std::nullopt;
  // The radial terms are centred on the apex: re-centre on the model's extreme until
  // it stays put (an off-centre quartic cannot follow the apex's flattening).
  double cx = 0.0, cy = 0.0;
  std::optional<ApexFit> fit;
  for (int round = 0; round < 4; ++round) {
    const auto f = fit_at(samples, cx, cy, radius, sign, round_window);
    if (!f) break;
    fit = f;
    if (std::hypot(f->x, f->y) < 0.05) break;
    cx += f->x * radius, cy += f->y * radius;
    if (std::hypot(cx, cy) > 0.5 * radius) break;  // wandered off: keep the last fit
  }
  if (!fit) return std::nullopt;
  return fit->value;
}

}  // namespace

std::optional<double> fit_apex_height(const std::vector<ApexSample>& samples, double radius, double sign) {
  return fit_apex(samples, radius, sign, true);
}

std::optional<double> fit_apex_height(const std::vector<ApexSample>& samples, double radius, double sign,
                                      const Eigen::Vector2d& along, double stretch) {
  if (!(stretch >= 1.0) || !along.allFinite() || !(along.norm() > 0.0)) return std::nullopt;
  const Eigen::Vector2d a = along.normalized();
  std::vector<ApexSample> disc;
  disc.reserve(samples.size());
  for (const auto& s : samples)
    disc.push_back({(a.x() * s.x + a.y() * s.y) / stretch, -a.y() * s.x + a.x() * s.y, s.deviation});
  return fit_apex(disc, radius, sign, stretch == 1.0);
}

}  // namespace dentmark::detect
