#include "dentmark/host/detect/reference_surface.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "hot_loop.h"
#include "threads.h"

namespace dentmark::detect {
namespace {

double binom(int n, int k) {
  static const double t[5][5] = {
      {1, 0, 0, 0, 0}, {1, 1, 0, 0, 0}, {1, 2, 1, 0, 0}, {1, 3, 3, 1, 0}, {1, 4, 6, 4, 1}};
  return t[n][k];
}

// Tiles within `radius` (Chebyshev) of a marked one.
std::vector<std::uint8_t> grow(const std::vector<std::uint8_t>& marked, int nx, int ny, int radius) {
  std::vector<std::uint8_t> rows(marked.size(), 0), out(marked.size(), 0);
  for (int y = 0; y < ny; ++y)
    for (int x = 0; x < nx; ++x)
      if (marked[static_cast<std::size_t>(y) * nx + x])
        for (int k = std::max(0, x - radius); k <= std::min(nx - 1, x + radius); ++k)
          rows[static_cast<std::size_t>(y) * nx + k] = 1;
  for (int y = 0; y < ny; ++y)
    for (int x = 0; x < nx; ++x)
      if (rows[static_cast<std::size_t>(y) * nx + x])
        for (int k = std::max(0, y - radius); k <= std::min(ny - 1, y + radius); ++k)
          out[static_cast<std::size_t>(k) * nx + x] = 1;
  return out;
}

// A window less full than this (of the map's own weight in it) is widened.
constexpr double kMinFill = 0.25;

std::vector<int> marked_list(const std::vector<std::uint8_t>& marked) {
  std::vector<int> list;
  for (std::size_t i = 0; i < marked.size(); ++i)
    if (marked[i]) list.push_back(static_cast<int>(i));
  return list;
}

}  // namespace

ReferenceSurface::ReferenceSurface(const HeightMap& map, double window) : map_(map) {
  const double px = map.pixel;
  tile_ = std::max(4, static_cast<int>(std::lround(window / (8.0 * px))));
  radius_ = std::max(1, static_cast<int>(std::lround(window / (2.0 * tile_ * px))));
  tiles_x_ = (map.cols + tile_ - 1) / tile_;
  tiles_y_ = (map.rows + tile_ - 1) / tile_;
  // Global coordinates scaled to about [-1, 1] for the moments.
  gu_ = map.u0 + 0.5 * map.cols * px;
  gv_ = map.v0 + 0.5 * map.rows * px;
  gs_ = 2.0 / (std::max(map.cols, map.rows) * px);
  local_scale_ = 1.0 / (radius_ * tile_ * px);
  // The map's own weight per tile, summed as an integral image.
  const int ic = tiles_x_ + 1;
  capacity_.assign(static_cast<std::size_t>(ic) * (tiles_y_ + 1), 0.0);
  // (A tile row per thread: each tile's weights are summed in the same order as by one.)
#pragma omp parallel for schedule(static)
  for (int ty = 0; ty < tiles_y_; ++ty)
    for (int r = ty * tile_; r < std::min(map.rows, (ty + 1) * tile_); ++r)
      for (int c = 0; c < map.cols; ++c) {
        const float w = map.weight[static_cast<std::size_t>(r) * map.cols + c];
        if (w > 0.0f) capacity_[static_cast<std::size_t>(ty + 1) * ic + c / tile_ + 1] += w;
      }
  for (int ty = 1; ty <= tiles_y_; ++ty)
    for (int tx = 1; tx <= tiles_x_; ++tx)
      capacity_[static_cast<std::size_t>(ty) * ic + tx] +=
          capacity_[static_cast<std::size_t>(ty - 1) * ic + tx] +
          capacity_[static_cast<std::size_t>(ty) * ic + tx - 1] -
          capacity_[static_cast<std::size_t>(ty - 1) * ic + tx - 1];
}

double ReferenceSurface::capacity_at(int tx, int ty, int radius) const {
  const int ic = tiles_x_ + 1;
  const int x0 = std::max(0, tx - radius), x1 = std::min(tiles_x_, tx + radius + 1),
            y0 = std::max(0, ty - radius), y1 = std::min(tiles_y_, ty + radius + 1);
  return capacity_[static_cast<std::size_t>(y1) * ic + x1] -
         capacity_[static_cast<std::size_t>(y0) * ic + x1] -
         capacity_[static_cast<std::size_t>(y1) * ic + x0] +
         capacity_[static_cast<std::size_t>(y0) * ic + x0];
}

DENTMARK_HOT_LOOP ReferenceSurface::Moments ReferenceSurface::tile_moments(
    int tx, int ty, const std::vector<float>& weights) const {
  // The sums in local variables (registers), term by term in the same order as the
  // definition: Σ ω x^a y^b with x^a y^b formed as ((ω x^a) y) y ...
  double m[15] = {}, hz[6] = {}, zz = 0.0;
  for (int r = ty * tile_; r < std::min(map_.rows, (ty + 1) * tile_); ++r)
    for (int c = tx * tile_; c < std::min(map_.cols, (tx + 1) * tile_); ++c) {
      const std::size_t k = static_cast<std::size_t>(r) * map_.cols + c;
      const double om = weights[k];
      if (!(om > 0.0)) continue;
      const double x = (map_.u[k] - gu_) * gs_, y = (map_.v[k] - gv_) * gs_, z = map_.w[k];
      const double x0 = om, x1 = x0 * x, x2 = x1 * x, x3 = x2 * x, x4 = x3 * x;
      const double x0y1 = x0 * y, x0y2 = x0y1 * y, x0y3 = x0y2 * y, x0y4 = x0y3 * y;
      const double x1y1 = x1 * y, x1y2 = x1y1 * y, x1y3 = x1y2 * y;
      const double x2y1 = x2 * y, x2y2 = x2y1 * y;
      const double x3y1 = x3 * y;
      m[0] += x0, m[1] += x0y1, m[2] += x0y2, m[3] += x0y3, m[4] += x0y4;
      m[5] += x1, m[6] += x1y1, m[7] += x1y2, m[8] += x1y3;
      m[9] += x2, m[10] += x2y1, m[11] += x2y2;
      m[12] += x3, m[13] += x3y1;
      m[14] += x4;
      hz[0] += x0 * z, hz[1] += x0y1 * z, hz[2] += x0y2 * z;
      hz[3] += x1 * z, hz[4] += x1y1 * z;
      hz[5] += x2 * z;
      zz += om * z * z;
    }
  Moments mo;
  static constexpr int ma[15] = {0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 3, 3, 4};
  static constexpr int mb[15] = {0, 1, 2, 3, 4, 0, 1, 2, 3, 0, 1, 2, 0, 1, 0};
  for (int i = 0; i < 15; ++i) mo.m[ma[i] * 5 + mb[i]] = m[i];
  static constexpr int ha[6] = {0, 0, 0, 1, 1, 2}, hb[6] = {0, 1, 2, 0, 1, 0};
  for (int i = 0; i < 6; ++i) mo.h[ha[i] * 3 + hb[i]] = hz[i];
  mo.zz = zz;
  return mo;
}

void ReferenceSurface::integrate() {
  const int ic = tiles_x_ + 1;
  // (Sized by the first fit, zeros.) Row 0 and column 0 stay zero; every other entry is
  // written below.
  for (int ty = 0; ty < tiles_y_; ++ty)
    for (int tx = 0; tx < tiles_x_; ++tx) {
      Moments& o = integral_[static_cast<std::size_t>(ty + 1) * ic + tx + 1];
      const Moments &a = integral_[static_cast<std::size_t>(ty) * ic + tx + 1],
                    &b = integral_[static_cast<std::size_t>(ty + 1) * ic + tx],
                    &d = integral_[static_cast<std::size_t>(ty) * ic + tx],
                    &t = tiles_[static_cast<std::size_t>(ty) * tiles_x_ + tx];
      for (int i = 0; i < 25; ++i) o.m[i] = a.m[i] + b.m[i] - d.m[i] + t.m[i];
      for (int i = 0; i < 9; ++i) o.h[i] = a.h[i] + b.h[i] - d.h[i] + t.h[i];
      o.zz = a.zz + b.zz - d.zz + t.zz;
    }
}

ReferenceSurface::Moments ReferenceSurface::window_at(int tx, int ty, int radius) const {
  const int ic = tiles_x_ + 1;
  const int x0 = std::max(0, tx - radius), x1 = std::min(tiles_x_, tx + radius + 1),
            y0 = std::max(0, ty - radius), y1 = std::min(tiles_y_, ty + radius + 1);
  Moments win;
  const Moments &A = integral_[static_cast<std::size_t>(y1) * ic + x1],
                &B = integral_[static_cast<std::size_t>(y0) * ic + x1],
                &C = integral_[static_cast<std::size_t>(y1) * ic + x0],
                &D = integral_[static_cast<std::size_t>(y0) * ic + x0];
  for (int i = 0; i < 25; ++i) win.m[i] = A.m[i] - B.m[i] - C.m[i] + D.m[i];
  for (int i = 0; i < 9; ++i) win.h[i] = A.h[i] - B.h[i] - C.h[i] + D.h[i];
  win.zz = A.zz - B.zz - C.zz + D.zz;
  return win;
}

// Where the panel curves too fast for a quadratic over the whole window (a fender's
// side, 50-60 degrees to the map plane, turns by 20 degrees across it), the fit over half
// the window has a far smaller residual: noise leaves both the same, and a defect (or a
// handle) in the window raises the half window's more. Then the half window's fit is
// used. The choice depends on the window's sums alone, so a refit still equals a fit
// from scratch.
ReferenceSurface::Quadratic ReferenceSurface::fit_at(int tx, int ty) const {
  double whole = 0.0, half = 0.0;
  const Moments window = window_at(tx, ty, radius_);
  // Where most of the window's pixels are left out (a handle and the margins around it,
  // a large defect), those left lie to one side, and their quadratic extrapolates to the
  // tile by up to millimetres (a false 0.75 mm dent beside a handle): the window twice as
  // wide then, if it is full enough, else no fit.
  if (window.m[0] < kMinFill * capacity_at(tx, ty, radius_)) {
    const Moments wider = window_at(tx, ty, 2 * radius_);
    Quadratic q = solve(wider, tx, ty, whole);
    q.ok = q.ok && wider.m[0] >= kMinFill * capacity_at(tx, ty, 2 * radius_);
    q.whole_mean_square = whole, q.wide = true;
    return q;
  }
  Quadratic q = solve(window, tx, ty, whole);
  const double whole_ms = whole;
  // (Tried everywhere: gated to slopes over 0.3, 2 of 501 door defects were lost.)
  if (radius_ >= 2 && q.ok) {
    // (Mostly full too: a sliver of pixels fits closely and extrapolates wildly.)
    const Moments half_window = window_at(tx, ty, radius_ / 2);
    Quadratic small = solve(half_window, tx, ty, half);
    if (small.ok && whole > 2.0 * half && half_window.m[0] >= kMinFill * capacity_at(tx, ty, radius_ / 2)) {
      q = small;
      double quarter = 0.0;
      // ... and, where the panel is steeper than 45 degrees to the map plane, so may a
      // quarter window's.
      const double slope = std::hypot(small.c(1), small.c(2)) * local_scale_;
      if (radius_ >= 4 && slope > 1.0) {
        // Mostly full: around a large defect, left out of the refit, a quarter window
        // holds a sliver of ring, which it fits closely and extrapolates wildly.
        const Moments win = window_at(tx, ty, radius_ / 4);
        const double side = (2.0 * (radius_ / 4) + 1.0) * tile_;
        Quadratic smaller = solve(win, tx, ty, quarter);
        if (smaller.ok && half > 2.0 * quarter && win.m[0] > 0.6 * side * side) q = smaller;
      }
    }
  }
  q.whole_mean_square = whole_ms;  // windows of one size compare (fold_pass.cpp)
  return q;
}

ReferenceSurface::Quadratic ReferenceSurface::solve(const Moments& win, int tx, int ty,
                                                    double& mean_square) const {
  const double px = map_.pixel;
  Quadratic q;
  q.cu = map_.u0 + (tx * tile_ + 0.5 * tile_) * px;
  q.cv = map_.v0 + (ty * tile_ + 0.5 * tile_) * px;
  if (!(win.m[0] > 0.0)) return q;
  // Moments about the tile centre, Σ ω (x - dx)^a (y - dy)^b, rescaled x -> x * k.
  const double dx = (q.cu - gu_) * gs_, dy = (q.cv - gv_) * gs_, k = local_scale_ / gs_;
  const double px_[5] = {1, -dx, dx * dx, -dx * dx * dx, dx * dx * dx * dx};
  const double py_[5] = {1, -dy, dy * dy, -dy * dy * dy, dy * dy * dy * dy};
  const double ka[5] = {1, k, k * k, k * k * k, k * k * k * k};
  Moments cm;
  for (int a = 0; a <= 4; ++a)
    for (int b = 0; a + b <= 4; ++b) {
      double s = 0.0, hs = 0.0;
      for (int i = 0; i <= a; ++i)
        for (int j = 0; j <= b; ++j) {
          const double f = binom(a, i) * binom(b, j) * px_[a - i] * py_[b - j];
          s += f * win.m[i * 5 + j];
          if (a + b <= 2) hs += f * win.h[i * 3 + j];
        }
      cm.m[a * 5 + b] = s * ka[a + b];
      if (a + b <= 2) cm.h[a * 3 + b] = hs * ka[a + b];
    }
  // Basis 1, x, y, x², xy, y².
  static constexpr int pa[6] = {0, 1, 0, 2, 1, 0}, pb[6] = {0, 0, 1, 0, 1, 2};
  Eigen::Matrix<double, 6, 6> N;
  Eigen::Matrix<double, 6, 1> rhs;
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 6; ++j) N(i, j) = cm.m[(pa[i] + pa[j]) * 5 + pb[i] + pb[j]];
    rhs(i) = cm.h[pa[i] * 3 + pb[i]];
  }
  // Enough spread for a quadratic? Otherwise a plane, otherwise nothing.
  const double w0 = N(0, 0);
  const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(N);
  if (ldlt.info() == Eigen::Success && ldlt.vectorD().minCoeff() > 1e-6 * w0) {
    q.c = ldlt.solve(rhs);
    q.ok = q.c.allFinite();
  } else {
    const Eigen::Matrix3d N3 = N.topLeftCorner<3, 3>();
    const Eigen::LDLT<Eigen::Matrix3d> l3(N3);
    if (l3.info() == Eigen::Success && l3.vectorD().minCoeff() > 1e-6 * w0) {
      q.c.setZero();
      q.c.head<3>() = l3.solve(rhs.head<3>());
      q.ok = q.c.allFinite();
    }
  }
  // At the least-squares solution Σ ω (z - f)² = Σ ω z² - c . rhs.
  mean_square = q.ok ? std::max(0.0, win.zz - q.c.dot(rhs)) / w0 : 0.0;
  q.mean_square = mean_square, q.weight = w0;
  return q;
}

// The four fits a pixel blends, at tiles (iy + n / 2, ix + n % 2), each re-expanded
// about the first one's centre: once per (iy, ix) a span of blend() meets (not once per
// pixel row).
struct ReferenceSurface::BlendCorner {
  double about[4][6];
  bool ok[4];
  const Quadratic* q0;
};

std::vector<ReferenceSurface::BlendCorner> ReferenceSurface::blend_corners(int iy0, int ix0, int ny,
                                                                           int nx) const {
  std::vector<BlendCorner> corners(static_cast<std::size_t>(ny * nx));
  for (int jy = 0; jy < ny; ++jy)
    for (int jx = 0; jx < nx; ++jx) {
      BlendCorner& k = corners[static_cast<std::size_t>(jy * nx + jx)];
      for (int n = 0; n < 4; ++n) {
        const int dy = n / 2, dx = n % 2;
        const Quadratic& q =
            fits_[static_cast<std::size_t>(std::clamp(iy0 + jy + dy, 0, tiles_y_ - 1)) * tiles_x_ +
                  std::clamp(ix0 + jx + dx, 0, tiles_x_ - 1)];
        if (n == 0) k.q0 = &q;
        k.ok[n] = q.ok;
        if (!q.ok) continue;
        // Its quadratic in x = X - d, y = Y - e, expanded in X, Y (about q0's centre).
        const double d = (q.cu - k.q0->cu) * local_scale_, e = (q.cv - k.q0->cv) * local_scale_;
        const auto& c = q.c;
        const double about[6] = {c(0) - c(1) * d - c(2) * e + c(3) * d * d + c(4) * d * e + c(5) * e * e,
                                 c(1) - 2.0 * c(3) * d - c(4) * e,
                                 c(2) - c(4) * d - 2.0 * c(5) * e,
                                 c(3),
                                 c(4),
                                 c(5)};
        std::copy(about, about + 6, k.about[n]);
      }
    }
  return corners;
}

DENTMARK_HOT_LOOP void ReferenceSurface::blend(int ty, int tx0, int tx1) {
  const int T = tile_;
  const int c1 = std::min(map_.cols, tx1 * T), r1 = std::min(map_.rows, (ty + 1) * T);
  if (c1 <= tx0 * T || r1 <= ty * T) return;
  const float* u = map_.u.data();
  const float* v = map_.v.data();
  const float* weight = map_.weight.data();
  // A pixel's four nearest fits are those at tiles (iy + dy, ix + dx), dy, dx in {0, 1}.
  const auto lower = [T](int p) { return static_cast<int>(std::floor((p + 0.5) / T - 0.5)); };
  const int iy0 = lower(ty * T), ix0 = lower(tx0 * T);
  const int ny = lower(r1 - 1) - iy0 + 1, nx = lower(c1 - 1) - ix0 + 1;
  const std::vector<BlendCorner> corners = blend_corners(iy0, ix0, ny, nx);
  for (int r = ty * T; r < r1; ++r) {
    const double fy = (r + 0.5) / T - 0.5;
    const int iy = static_cast<int>(std::floor(fy));
    const double ay = fy - iy;
    // The tiles' columns in runs that share their four nearest fits: a run ends where
    // lower() steps, found from its arithmetic guess and checked with lower() itself.
    for (int c = tx0 * T, end = c; c < c1; c = end) {
      const int ix = lower(c);
      end = std::clamp(T * ix + (3 * T) / 2, c + 1, c1);
      while (end < c1 && lower(end) == ix) ++end;
      while (end > c + 1 && lower(end - 1) != ix) --end;
      // The four fits, (dy, dx) = (0, 0), (0, 1), (1, 0), (1, 1), weighted bilinearly:
      // fit n weighs (1 - ax or ax) * (1 - ay or ay) + 1e-9, or 0 if it failed. Along
      // the run only ax changes, so the blend is (A + ax B) / (wa + ax wb), with A and B
      // quadratics combined from the four, all about the first fit's centre.
      const BlendCorner& k = corners[static_cast<std::size_t>((iy - iy0) * nx + (ix - ix0))];
      double A[6] = {0, 0, 0, 0, 0, 0}, B[6] = {0, 0, 0, 0, 0, 0}, wa = 0.0, wb = 0.0;
      for (int n = 0; n < 4; ++n) {
        if (!k.ok[n]) continue;
        const int dy = n / 2, dx = n % 2;
        const double wy = dy ? ay : 1.0 - ay;
        const double alpha = dx ? 1e-9 : wy + 1e-9, beta = dx ? wy : -wy;
        for (int i = 0; i < 6; ++i) A[i] += alpha * k.about[n][i], B[i] += beta * k.about[n][i];
        wa += alpha, wb += beta;
      }
      if (!(wa > 0.0)) {  // no fit near: nothing is measured here
        std::fill(ref_.begin() + static_cast<std::ptrdiff_t>(r) * map_.cols + c,
                  ref_.begin() + static_cast<std::ptrdiff_t>(r) * map_.cols + end,
                  std::numeric_limits<float>::quiet_NaN());
        continue;
      }
      // The pixels in floats (twice as many per vector as doubles): X and Y are within a
      // few units, the heights within centimetres of the map plane, so the rounding stays
      // at nanometres.
      float Af[6], Bf[6];
      for (int i = 0; i < 6; ++i) Af[i] = static_cast<float>(A[i]), Bf[i] = static_cast<float>(B[i]);
      const auto waf = static_cast<float>(wa), wbf = static_cast<float>(wb);
      const auto cu = static_cast<float>(k.q0->cu), cv = static_cast<float>(k.q0->cv);
      const auto s = static_cast<float>(local_scale_), inv_t = 1.0f / static_cast<float>(T);
      const float ax0 = -0.5f - static_cast<float>(ix);
      float* out = ref_.data() + static_cast<std::size_t>(r) * map_.cols;
      const std::size_t row = static_cast<std::size_t>(r) * map_.cols;
#pragma omp simd
      for (int cc = c; cc < end; ++cc) {
        const float ax = (static_cast<float>(cc) + 0.5f) * inv_t + ax0;
        const float X = (u[row + cc] - cu) * s, Y = (v[row + cc] - cv) * s;
        const float a = Af[0] + Af[1] * X + Af[2] * Y + Af[3] * X * X + Af[4] * X * Y + Af[5] * Y * Y;
        const float b = Bf[0] + Bf[1] * X + Bf[2] * Y + Bf[3] * X * X + Bf[4] * X * Y + Bf[5] * Y * Y;
        const float val = (a + ax * b) / (waf + ax * wbf);
        out[cc] = weight[row + cc] > 0.0f ? val : std::numeric_limits<float>::quiet_NaN();
      }
    }
  }
}

double ReferenceSurface::height_at(double u, double v) const {
  if (fits_.empty()) return std::numeric_limits<double>::quiet_NaN();
  // As blend(): the fits at tiles (iy + dy, ix + dx), weighted bilinearly (+ 1e-9).
  const double fy = (v - map_.v0) / (map_.pixel * tile_) - 0.5,
               fx = (u - map_.u0) / (map_.pixel * tile_) - 0.5;
  const int iy = static_cast<int>(std::floor(fy)), ix = static_cast<int>(std::floor(fx));
  const double ay = fy - iy, ax = fx - ix;
  double sum = 0.0, wsum = 0.0;
  for (int n = 0; n < 4; ++n) {
    const int dy = n / 2, dx = n % 2;
    const Quadratic& q = fits_[static_cast<std::size_t>(std::clamp(iy + dy, 0, tiles_y_ - 1)) * tiles_x_ +
                               std::clamp(ix + dx, 0, tiles_x_ - 1)];
    if (!q.ok) continue;
    const double w = (dy ? ay : 1.0 - ay) * (dx ? ax : 1.0 - ax) + 1e-9;
    const double x = (u - q.cu) * local_scale_, y = (v - q.cv) * local_scale_;
    const auto& c = q.c;
    sum += w * (c(0) + c(1) * x + c(2) * y + c(3) * x * x + c(4) * x * y + c(5) * y * y);
    wsum += w;
  }
  return wsum > 0.0 ? sum / wsum : std::numeric_limits<double>::quiet_NaN();
}

const std::vector<float>& ReferenceSurface::fit(const std::vector<float>& weights) {
  const std::size_t tiles = static_cast<std::size_t>(tiles_x_) * tiles_y_;
  // The tiles whose weights changed since the last fit (all, the first time).
  std::vector<std::uint8_t> changed(tiles, 1);
  if (!weights_.empty()) {
#pragma omp parallel for schedule(dynamic, 4)
    for (int ty = 0; ty < tiles_y_; ++ty)
      for (int tx = 0; tx < tiles_x_; ++tx) {
        // Compared and, where they differ, taken over (no serial copy of the whole image).
        bool differs = false;
        const int c0 = tx * tile_, c1 = std::min(map_.cols, (tx + 1) * tile_);
        for (int r = ty * tile_; r < std::min(map_.rows, (ty + 1) * tile_); ++r) {
          const std::size_t row = static_cast<std::size_t>(r) * map_.cols;
          if (!differs)
            for (int c = c0; c < c1; ++c) differs = differs || weights[row + c] != weights_[row + c];
          if (differs)
            std::copy(weights.begin() + row + c0, weights.begin() + row + c1, weights_.begin() + row + c0);
        }
        // (Rows before the first difference were equal already.)
        changed[static_cast<std::size_t>(ty) * tiles_x_ + tx] = differs;
      }
    if (std::none_of(changed.begin(), changed.end(), [](std::uint8_t b) { return b != 0; })) return ref_;
    // The blend as it was before the last fold pass, which is redone from it below.
    for (const auto& [k, plain] : unfolded_) ref_[k] = plain;
  } else {
    // Fresh memory (a page fault per 4 KB), filled side by side.
    detail::side_by_side([&] { tiles_.resize(tiles); }, [&] { fits_.resize(tiles); },
                         [&] { integral_.resize(static_cast<std::size_t>(tiles_x_ + 1) * (tiles_y_ + 1)); },
                         [&] { ref_.assign(map_.size(), std::numeric_limits<float>::quiet_NaN()); },
                         [&] { weights_ = weights; });
  }

  const std::vector<int> moments = marked_list(changed);
#pragma omp parallel for schedule(dynamic, 16)
  for (std::size_t i = 0; i < moments.size(); ++i)
    tiles_[static_cast<std::size_t>(moments[i])] =
        tile_moments(moments[i] % tiles_x_, moments[i] / tiles_x_, weights);
  integrate();
  // A fit changes when its window holds a changed tile (a widened one, when its wider
  // window does); a pixel when one of its four nearest fits does (they are in its own
  // tile and the eight around it).
  std::vector<std::uint8_t> refit = grow(changed, tiles_x_, tiles_y_, radius_);
  {
    const std::vector<std::uint8_t> wider = grow(changed, tiles_x_, tiles_y_, 2 * radius_);
    for (std::size_t t = 0; t < tiles; ++t) refit[t] = refit[t] || (wider[t] && fits_[t].wide);
  }
  const std::vector<int> fits = marked_list(refit);
#pragma omp parallel for schedule(dynamic, 16)
  for (std::size_t i = 0; i < fits.size(); ++i)
    fits_[static_cast<std::size_t>(fits[i])] = fit_at(fits[i] % tiles_x_, fits[i] / tiles_x_);
  // Pixels are blended in spans of consecutive tiles of a tile row (a run of pixels
  // then spans a whole tile, not half of one).
  const std::vector<std::uint8_t> reblend = grow(refit, tiles_x_, tiles_y_, 1);
  struct Span {
    int ty, tx0, tx1;
  };
  std::vector<Span> spans;
  for (int ty = 0; ty < tiles_y_; ++ty)
    for (int tx = 0; tx < tiles_x_;) {
      if (!reblend[static_cast<std::size_t>(ty) * tiles_x_ + tx]) {
        ++tx;
        continue;
      }
      Span sp{ty, tx, tx};
      while (sp.tx1 < tiles_x_ && reblend[static_cast<std::size_t>(ty) * tiles_x_ + sp.tx1] &&
             sp.tx1 - sp.tx0 < 32)
        ++sp.tx1;
      spans.push_back(sp);
      tx = sp.tx1;
    }
#pragma omp parallel for schedule(dynamic, 4)
  for (std::size_t i = 0; i < spans.size(); ++i) blend(spans[i].ty, spans[i].tx0, spans[i].tx1);
  fold_pass();
  return ref_;
}

}  // namespace dentmark::detect
