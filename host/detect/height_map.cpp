#include "dentmark/host/detect/height_map.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace dentmark::detect {

long HeightMap::pixel_of(double pu, double pv) const {
  const double c = std::floor((pu - u0) / pixel), r = std::floor((pv - v0) / pixel);
  if (c < 0 || r < 0 || c >= cols || r >= rows) return -1;
  return static_cast<long>(r) * cols + static_cast<long>(c);
}

HeightMap build_height_map(const LinearOctree& tree, double pixel, double layer_depth) {
  const auto& leaves = tree.leaves();
  HeightMap map;
  map.pixel = pixel;
  // Plane through the area-weighted leaf centroids (weighted scatter of leaf means).
  double A = 0.0;
  Eigen::Vector3d P = Eigen::Vector3d::Zero(), S = Eigen::Vector3d::Zero();
  for (const auto& l : leaves)
    A += l.area, P += l.area * l.centroid.cast<double>(), S += l.sum_an.cast<double>();
  if (!(A > 0.0)) throw std::invalid_argument("scan has no surface area");
  const Eigen::Vector3d c = P / A;
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const auto& l : leaves) {
    if (!(l.area > 0.0)) continue;
    const Eigen::Vector3d d = l.centroid.cast<double>() - c;
    scatter += l.area * d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
  Eigen::Vector3d w = eig.eigenvectors().col(0).normalized();
  // Towards the sensor at the frame origin; if the origin lies on the plane, towards
  // the side the triangles face.
  const double side = w.dot(-c);
  if (std::abs(side) > 1e-3 ? side < 0 : w.dot(S) < 0) w = -w;
  Eigen::Vector3d u = eig.eigenvectors().col(2).normalized();
  u = (u - u.dot(w) * w).normalized();
  const Eigen::Vector3d v = w.cross(u);
  map.origin = c;
  map.axes.row(0) = u.transpose();
  map.axes.row(1) = v.transpose();
  map.axes.row(2) = w.transpose();
  map.viewpoint = map.to_map(Eigen::Vector3d::Zero());
  map.has_viewpoint = map.viewpoint.z() > 0.1;

  // Leaf centroids in map coordinates (floats: 0.1 µm over 2 m), and the bounds.
  const auto count = static_cast<std::int64_t>(leaves.size());
  std::vector<Eigen::Vector3f> q(leaves.size());
  double umin = 1e18, umax = -1e18, vmin = 1e18, vmax = -1e18;
#pragma omp parallel for schedule(static) reduction(min : umin, vmin) reduction(max : umax, vmax)
  for (std::int64_t i = 0; i < count; ++i) {
    if (!(leaves[i].area > 0.0f)) continue;
    const Eigen::Vector3d p = map.to_map(leaves[i].centroid.cast<double>());
    q[i] = p.cast<float>();
    umin = std::min(umin, p.x()), umax = std::max(umax, p.x());
    vmin = std::min(vmin, p.y()), vmax = std::max(vmax, p.y());
  }
  map.u0 = umin - pixel, map.v0 = vmin - pixel;
  map.cols = static_cast<int>((umax - map.u0) / pixel) + 2;
  map.rows = static_cast<int>((vmax - map.v0) / pixel) + 2;
  if (static_cast<double>(map.cols) * map.rows > 4e8) throw std::invalid_argument("height map too large");
  const std::size_t n = map.size();
  std::vector<std::int32_t> pix(leaves.size(), -1);
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < count; ++i)
    if (leaves[i].area > 0.0f) pix[i] = static_cast<std::int32_t>(map.pixel_of(q[i].x(), q[i].y()));
  // A single view sees the front surface of each column. Leaves more than layer_depth
  // behind the column's front were seen through a hole (or are outliers): kept aside.
  // (Anchoring on the column's busiest leaf instead lets a hole's backdrop win the rim
  // columns; an outlier in front only spoils its own pixel, which the median removes.)
  std::vector<float> front(n, -std::numeric_limits<float>::infinity());
  for (std::size_t i = 0; i < leaves.size(); ++i)
    if (pix[i] >= 0) front[pix[i]] = std::max(front[pix[i]], q[i].z());
  // Area-weighted sums per pixel, straight into the map's arrays (a pixel holds one or two
  // leaves: float sums lose nothing), then divided in place.
  map.weight.assign(n, 0.0f);
  map.u.assign(n, 0.0f), map.v.assign(n, 0.0f), map.w.assign(n, 0.0f);
  std::vector<Eigen::Vector3f> sn(n, Eigen::Vector3f::Zero());
  const auto layer = static_cast<float>(layer_depth);
  for (std::size_t i = 0; i < leaves.size(); ++i) {
    const std::int32_t k = pix[i];
    if (k < 0) continue;
    if (q[i].z() < front[k] - layer) {
      map.behind.push_back(q[i]);
      continue;
    }
    const float a = leaves[i].area;
    map.weight[k] += a, map.u[k] += a * q[i].x(), map.v[k] += a * q[i].y(), map.w[k] += a * q[i].z();
    sn[k] += leaves[i].sum_an;
  }
  map.cos_tilt.assign(n, 1.0f);
  const Eigen::Vector3f wf = w.cast<float>();
  const auto inv_px2 = static_cast<float>(1.0 / (pixel * pixel));
#pragma omp parallel for schedule(static)
  for (std::int64_t k = 0; k < static_cast<std::int64_t>(n); ++k) {
    const float a = map.weight[k];
    if (!(a > 0.0f)) continue;
    map.u[k] /= a, map.v[k] /= a, map.w[k] /= a;
    map.weight[k] = a * inv_px2;
    const float nn = sn[k].norm();
    map.cos_tilt[k] = nn > 0 ? std::abs(sn[k].dot(wf)) / nn : 1.0f;
  }
  return map;
}

namespace {

// Moments of a tile or window: Σ ω x^a y^b (a + b <= 4) and Σ ω z x^a y^b (a + b <= 2)
// in coordinates scaled to about [-1, 1].
struct Moments {
  std::array<double, 25> m{};  // m[a * 5 + b]
  std::array<double, 9> h{};   // h[a * 3 + b]
};

double binom(int n, int k) {
  static const double t[5][5] = {
      {1, 0, 0, 0, 0}, {1, 1, 0, 0, 0}, {1, 2, 1, 0, 0}, {1, 3, 3, 1, 0}, {1, 4, 6, 4, 1}};
  return t[n][k];
}

// Moments about a point shifted by (dx, dy): Σ ω (x - dx)^a (y - dy)^b.
Moments shift(const Moments& in, double dx, double dy) {
  double px[5] = {1, -dx, dx * dx, -dx * dx * dx, dx * dx * dx * dx};
  double py[5] = {1, -dy, dy * dy, -dy * dy * dy, dy * dy * dy * dy};
  Moments out;
  for (int a = 0; a <= 4; ++a)
    for (int b = 0; a + b <= 4; ++b) {
      double s = 0.0, hs = 0.0;
      for (int i = 0; i <= a; ++i)
        for (int j = 0; j <= b; ++j) {
          const double f = binom(a, i) * binom(b, j) * px[a - i] * py[b - j];
          s += f * in.m[i * 5 + j];
          if (a + b <= 2) hs += f * in.h[i * 3 + j];
        }
      out.m[a * 5 + b] = s;
      if (a + b <= 2) out.h[a * 3 + b] = hs;
    }
  return out;
}

}  // namespace

std::vector<float> fit_reference(const HeightMap& map, const std::vector<float>& weights, double window) {
  const double px = map.pixel;
  const int T = std::max(4, static_cast<int>(std::lround(window / (8.0 * px))));
  const int R = std::max(1, static_cast<int>(std::lround(window / (2.0 * T * px))));
  const int tc = (map.cols + T - 1) / T, tr = (map.rows + T - 1) / T;
  // Global coordinates scaled to about [-1, 1]; integral images over tiles.
  const double gu = map.u0 + 0.5 * map.cols * px, gv = map.v0 + 0.5 * map.rows * px;
  const double gs = 2.0 / (std::max(map.cols, map.rows) * px);
  std::vector<Moments> tiles(static_cast<std::size_t>(tc) * tr);
#pragma omp parallel for schedule(dynamic, 4)
  for (int ty = 0; ty < tr; ++ty)
    for (int tx = 0; tx < tc; ++tx) {
      Moments mo;
      for (int r = ty * T; r < std::min(map.rows, (ty + 1) * T); ++r)
        for (int c = tx * T; c < std::min(map.cols, (tx + 1) * T); ++c) {
          const std::size_t k = static_cast<std::size_t>(r) * map.cols + c;
          const double om = weights[k];
          if (!(om > 0.0)) continue;
          const double x = (map.u[k] - gu) * gs, y = (map.v[k] - gv) * gs, z = map.w[k];
          double xa = om;
          for (int a = 0; a <= 4; ++a) {
            double xy = xa;
            for (int b = 0; a + b <= 4; ++b) {
              mo.m[a * 5 + b] += xy;
              if (a + b <= 2) mo.h[a * 3 + b] += xy * z;
              xy *= y;
            }
            xa *= x;
          }
        }
      tiles[static_cast<std::size_t>(ty) * tc + tx] = mo;
    }
  // Integral image of the tile moments.
  const int ic = tc + 1;
  std::vector<Moments> integ(static_cast<std::size_t>(ic) * (tr + 1));
  for (int ty = 0; ty < tr; ++ty)
    for (int tx = 0; tx < tc; ++tx) {
      Moments& o = integ[static_cast<std::size_t>(ty + 1) * ic + tx + 1];
      const Moments &a = integ[static_cast<std::size_t>(ty) * ic + tx + 1],
                    &b = integ[static_cast<std::size_t>(ty + 1) * ic + tx],
                    &d = integ[static_cast<std::size_t>(ty) * ic + tx],
                    &t = tiles[static_cast<std::size_t>(ty) * tc + tx];
      for (int i = 0; i < 25; ++i) o.m[i] = a.m[i] + b.m[i] - d.m[i] + t.m[i];
      for (int i = 0; i < 9; ++i) o.h[i] = a.h[i] + b.h[i] - d.h[i] + t.h[i];
    }
  // Quadratic at each tile centre, in local coordinates scaled by the window.
  const double ls = 1.0 / (R * T * px);  // local scale
  struct Quad {
    bool ok = false;
    double cu = 0, cv = 0;
    Eigen::Matrix<double, 6, 1> c;
  };
  std::vector<Quad> quads(tiles.size());
#pragma omp parallel for schedule(dynamic, 8)
  for (int ty = 0; ty < tr; ++ty)
    for (int tx = 0; tx < tc; ++tx) {
      const int x0 = std::max(0, tx - R), x1 = std::min(tc, tx + R + 1), y0 = std::max(0, ty - R),
                y1 = std::min(tr, ty + R + 1);
      Moments win;
      const Moments &A = integ[static_cast<std::size_t>(y1) * ic + x1],
                    &B = integ[static_cast<std::size_t>(y0) * ic + x1],
                    &C = integ[static_cast<std::size_t>(y1) * ic + x0],
                    &D = integ[static_cast<std::size_t>(y0) * ic + x0];
      for (int i = 0; i < 25; ++i) win.m[i] = A.m[i] - B.m[i] - C.m[i] + D.m[i];
      for (int i = 0; i < 9; ++i) win.h[i] = A.h[i] - B.h[i] - C.h[i] + D.h[i];
      Quad& q = quads[static_cast<std::size_t>(ty) * tc + tx];
      q.cu = map.u0 + (tx * T + 0.5 * T) * px;
      q.cv = map.v0 + (ty * T + 0.5 * T) * px;
      if (!(win.m[0] > 0.0)) continue;
      // Centre on the tile, then rescale x -> x * (ls / gs).
      Moments cm = shift(win, (q.cu - gu) * gs, (q.cv - gv) * gs);
      const double k = ls / gs;
      double ka[5] = {1, k, k * k, k * k * k, k * k * k * k};
      for (int a = 0; a <= 4; ++a)
        for (int b = 0; a + b <= 4; ++b) {
          cm.m[a * 5 + b] *= ka[a + b];
          if (a + b <= 2) cm.h[a * 3 + b] *= ka[a + b];
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
      const double minpiv = ldlt.vectorD().minCoeff();
      if (ldlt.info() == Eigen::Success && minpiv > 1e-6 * w0) {
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
    }
  // Blend the four nearest tile fits at each pixel.
  std::vector<float> ref(map.size(), std::numeric_limits<float>::quiet_NaN());
#pragma omp parallel for schedule(static)
  for (int r = 0; r < map.rows; ++r)
    for (int c = 0; c < map.cols; ++c) {
      const std::size_t k = static_cast<std::size_t>(r) * map.cols + c;
      if (!(map.weight[k] > 0.0f)) continue;
      const double fx = (c + 0.5) / T - 0.5, fy = (r + 0.5) / T - 0.5;
      const int ix = static_cast<int>(std::floor(fx)), iy = static_cast<int>(std::floor(fy));
      const double ax = fx - ix, ay = fy - iy;
      double sum = 0.0, wsum = 0.0;
      for (int dy = 0; dy <= 1; ++dy)
        for (int dx = 0; dx <= 1; ++dx) {
          const int qx = std::clamp(ix + dx, 0, tc - 1), qy = std::clamp(iy + dy, 0, tr - 1);
          const Quad& q = quads[static_cast<std::size_t>(qy) * tc + qx];
          if (!q.ok) continue;
          const double wgt = (dx ? ax : 1 - ax) * (dy ? ay : 1 - ay) + 1e-9;
          const double x = (map.u[k] - q.cu) * ls, y = (map.v[k] - q.cv) * ls;
          const double val =
              q.c(0) + q.c(1) * x + q.c(2) * y + q.c(3) * x * x + q.c(4) * x * y + q.c(5) * y * y;
          sum += wgt * val, wsum += wgt;
        }
      if (wsum > 0) ref[k] = static_cast<float>(sum / wsum);
    }
  return ref;
}

}  // namespace dentmark::detect
