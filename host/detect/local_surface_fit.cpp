#include "local_surface_fit.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "dentmark/common/nth_smallest.h"

namespace dentmark::detect {
namespace {

// Tukey's biweight constant, in robust σ of the annulus's residuals: 95 % efficiency
// under Gaussian noise (Huber, "Robust Statistics", §7.8).
constexpr double kTukeyC = 4.685;
// The smallest robust σ the weights are computed for (m): a noiseless synthetic ring
// would otherwise give every residual of a rounding error zero weight.
constexpr double kSigmaFloor = 1e-7;
// At most this many grid cells per axis; a wider spread of points takes wider cells.
constexpr double kMaxCellsPerAxis = 4096.0;
// Concentration steps from the least-squares start (robust_quadratic_residual).
constexpr int kTrimmedSteps = 4;

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

Vector6d monomials(double x, double y) {
  return (Vector6d() << 1.0, x, y, x * x, x * y, y * y).finished();
}

// Weighted least squares of w over the monomials (x, y scaled by 'scale'); false when
// ill-conditioned (the annulus on one side of a border, say).
bool solve_quadratic(const std::vector<Eigen::Vector3d>& ring, const std::vector<double>& weight,
                     double scale, Vector6d& coef) {
  Matrix6d a = Matrix6d::Zero();
  Vector6d b = Vector6d::Zero();
  for (std::size_t j = 0; j < ring.size(); ++j) {
    if (!(weight[j] > 0.0)) continue;
    const Vector6d m = monomials(ring[j].x() * scale, ring[j].y() * scale);
    a.selfadjointView<Eigen::Lower>().rankUpdate(m, weight[j]);
    b += weight[j] * ring[j].z() * m;
  }
  a = a.selfadjointView<Eigen::Lower>();
  const Eigen::LDLT<Matrix6d> ldlt(a);
  if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-10)) return false;
  coef = ldlt.solve(b);
  return coef.allFinite();
}

}  // namespace

double robust_quadratic_residual(double w0, const std::vector<Eigen::Vector3d>& ring,
                                 const LocalFitOptions& options) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (static_cast<int>(ring.size()) < options.min_points) return nan;
  const double scale = 1.0 / options.outer_radius;  // coordinates in about [-1, 1]
  std::vector<double> weight(ring.size(), 1.0), residual(ring.size());
  std::vector<double> abs_residual;
  Vector6d coef;
  if (!solve_quadratic(ring, weight, scale, coef)) return nan;
  const auto update_residuals = [&] {
    abs_residual.clear();
    for (std::size_t j = 0; j < ring.size(); ++j) {
      residual[j] = ring[j].z() - monomials(ring[j].x() * scale, ring[j].y() * scale).dot(coef);
      abs_residual.push_back(std::abs(residual[j]));
    }
  };
  // The biweight only refines a fit that is near the surface already: from a least-squares
  // start that a handle's wall over a third of the annulus has pulled millimetres up, it
  // settles between wall and panel. Concentration steps of least trimmed squares
  // (Rousseeuw and Van Driessen, "Computing LTS regression for large data sets", 2006)
  // refit the half of the annulus closest to the last fit; none raises the trimmed sum of
  // squares, and a few reach a wall-free half from a start a wall has tilted.
  for (int step = 0; step < kTrimmedSteps; ++step) {
    update_residuals();
    std::vector<double> sorted = abs_residual;
    const double half = nth_smallest(sorted, sorted.size() / 2);
    for (std::size_t j = 0; j < ring.size(); ++j) weight[j] = abs_residual[j] <= half ? 1.0 : 0.0;
    if (!solve_quadratic(ring, weight, scale, coef)) return nan;
  }
  for (int it = 0; it < options.iterations; ++it) {
    update_residuals();
    const double c = kTukeyC * std::max(robust_sigma(abs_residual), kSigmaFloor);
    int kept = 0;
    for (std::size_t j = 0; j < ring.size(); ++j) {
      const double t = residual[j] / c;
      weight[j] = std::abs(t) < 1.0 ? (1.0 - t * t) * (1.0 - t * t) : 0.0;
      kept += weight[j] > 0.0;
    }
    if (kept < options.min_points || !solve_quadratic(ring, weight, scale, coef)) return nan;
  }
  // The surface's slope at the vertex turns the offset in w into one along its normal.
  const double gx = coef[1] * scale, gy = coef[2] * scale;
  return (w0 - coef[0]) / std::sqrt(1.0 + gx * gx + gy * gy);
}

std::vector<float> local_surface_residuals(const std::vector<Eigen::Vector3f>& points,
                                           const LocalFitOptions& options) {
  const std::size_t n = points.size();
  std::vector<float> out(n, std::numeric_limits<float>::quiet_NaN());
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::max()), hi = -lo;
  for (const auto& p : points)
    if (p.allFinite())
      lo = lo.cwiseMin(p.head<2>().cast<double>()), hi = hi.cwiseMax(p.head<2>().cast<double>());
  if (!(hi.x() >= lo.x())) return out;
  // A uniform grid of cells at least the annulus's outer radius wide: each vertex's
  // neighbours are in its own cell and the eight around it.
  const double cell = std::max(options.outer_radius, (hi - lo).maxCoeff() / kMaxCellsPerAxis);
  const int cols = static_cast<int>((hi.x() - lo.x()) / cell) + 1,
            rows = static_cast<int>((hi.y() - lo.y()) / cell) + 1;
  const auto cell_of = [&](const Eigen::Vector3f& p) {
    const int c = std::min(cols - 1, static_cast<int>((p.x() - lo.x()) / cell));
    const int r = std::min(rows - 1, static_cast<int>((p.y() - lo.y()) / cell));
    return static_cast<std::size_t>(r) * static_cast<std::size_t>(cols) + static_cast<std::size_t>(c);
  };
  std::vector<std::uint32_t> start(static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols) + 1, 0),
      order;
  for (const auto& p : points)
    if (p.allFinite()) ++start[cell_of(p) + 1];
  for (std::size_t k = 1; k < start.size(); ++k) start[k] += start[k - 1];
  order.resize(start.back());
  {
    std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
    for (std::size_t i = 0; i < n; ++i)
      if (points[i].allFinite()) order[fill[cell_of(points[i])]++] = static_cast<std::uint32_t>(i);
  }
  const double r_in2 = options.inner_radius * options.inner_radius;
  const double r_out2 = options.outer_radius * options.outer_radius;
#pragma omp parallel
  {
    std::vector<Eigen::Vector3d> ring;
#pragma omp for schedule(dynamic, 256)
    for (std::int64_t i = 0; i < static_cast<std::int64_t>(n); ++i) {
      const Eigen::Vector3f& p = points[static_cast<std::size_t>(i)];
      if (!p.allFinite()) continue;
      ring.clear();
      const std::size_t k = cell_of(p);
      const int r0 = static_cast<int>(k / static_cast<std::size_t>(cols)),
                c0 = static_cast<int>(k % static_cast<std::size_t>(cols));
      for (int r = std::max(0, r0 - 1); r <= std::min(rows - 1, r0 + 1); ++r)
        for (int c = std::max(0, c0 - 1); c <= std::min(cols - 1, c0 + 1); ++c) {
          const std::size_t cc =
              static_cast<std::size_t>(r) * static_cast<std::size_t>(cols) + static_cast<std::size_t>(c);
          for (std::uint32_t q = start[cc]; q < start[cc + 1]; ++q) {
            const Eigen::Vector3d d = (points[order[q]] - p).cast<double>();
            const double r2 = d.head<2>().squaredNorm();
            if (r2 >= r_in2 && r2 <= r_out2) ring.push_back(d);
          }
        }
      out[static_cast<std::size_t>(i)] = static_cast<float>(robust_quadratic_residual(0.0, ring, options));
    }
  }
  return out;
}

}  // namespace dentmark::detect
