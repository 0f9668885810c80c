#include "measure_candidate.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <numbers>
#include <optional>

namespace dentmark::detect {
namespace {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

// A ring whose residual about its own quadratic exceeds this many times the map's
// deviation noise is not a smooth panel: the candidate cannot be measured as a dent
// there, and is taken as part of the design around it.
constexpr double kRoughRing = 3.5;
// ... and this fraction of the smallest defect height. Without it a scan with no noise
// (a mesh made from CAD or by a simulator) was rough everywhere: its deviation noise is
// float rounding, 0.04 um, and a clean ring's residual 0.03-0.3 um; a 24 mm, 0.44 mm
// deep dent was taken for design; and a ring holding a noise-free defect's own rim
// (a 61 um bump's 15 um trough) is off by a few um. A strip no quadratic follows is off
// by tens of um.
constexpr double kSmoothRingFloor = 0.5;

// A scan vertex this far off the reference is not the panel's skin but something seen
// past it through a gap between its samples (a wall 0.6 m behind gave "dents" 640 mm
// deep, measured on the wall's vertices); no dent or bump is that deep.
constexpr double kFarSample = 0.02;

// A single vertex standing out by this many times the deviation's noise, with none beside
// it at half its height, is an outlier (coarse scans, which have no spike test).
constexpr double kSingleSample = 20.0;

// A pixel's reference this close to the blend of tile fits is the blend's.
constexpr double kSameHeight = 1e-7;

// The pixels a candidate is measured in: its bounding box grown by a margin.
struct Box {
  int r0 = 0, r1 = 0, c0 = 0, c1 = 0;      // the candidate's own bounds
  int br0 = 0, br1 = 0, bc0 = 0, bc1 = 0;  // with the margin, clipped to the map
  int margin = 0;
  int width() const { return bc1 - bc0 + 1; }
  int height() const { return br1 - br0 + 1; }
  bool contains(int r, int c) const { return r >= br0 && r <= br1 && c >= bc0 && c <= bc1; }
  std::size_t index(int r, int c) const { return static_cast<std::size_t>((r - br0) * width() + (c - bc0)); }
};

Box box_around(const std::vector<std::int32_t>& pixels, const HeightMap& map, double length) {
  const int cols = map.cols, rows = map.rows;
  const double h = map.pixel;
  Box b;
  b.c0 = cols, b.c1 = 0, b.r0 = rows, b.r1 = 0;
  for (auto k : pixels)
    b.c0 = std::min(b.c0, k % cols), b.c1 = std::max(b.c1, k % cols), b.r0 = std::min(b.r0, k / cols),
    b.r1 = std::max(b.r1, k / cols);
  b.margin = std::max(6, static_cast<int>(std::lround(std::max(length / h, 0.012 / h))));
  b.bc0 = std::max(0, b.c0 - b.margin), b.bc1 = std::min(cols - 1, b.c1 + b.margin);
  b.br0 = std::max(0, b.r0 - b.margin), b.br1 = std::min(rows - 1, b.r1 + b.margin);
  return b;
}

// The reference a candidate is measured against: a quadratic fitted to the clean ring
// of panel around it (the candidate, its faint rim, spikes, borders and holes left out),
// or, where the panel curves too fast for a quadratic across the ring (a fender's side)
// but the global reference follows it, the global reference plus a quadratic correction.
class LocalReference {
 public:
  LocalReference(const CandidateScene& scene, const Box& box, double length, const Eigen::Vector2d& mean)
      : scene_(scene) {
    const HeightMap& map = scene.map;
    const int cols = map.cols;
    const double h = map.pixel;
    cu_ = mean.x() * h + map.u0, cv_ = mean.y() * h + map.v0;
    sc_ = 1.0 / (box.margin * h + 0.5 * length);
    Matrix6d N = Matrix6d::Zero();
    Vector6d rhs = Vector6d::Zero(), rhs_off = Vector6d::Zero();
    double ring_ww = 0.0;    // Σ weight · w², for the ring's residual
    double ring_off2 = 0.0;  // the same of the departure from the global reference
    int ring = 0;
    const int guard = std::max(2, static_cast<int>(std::lround(0.25 * length / h)));
    for (int r = box.br0; r <= box.br1; ++r)
      for (int c = box.bc0; c <= box.bc1; ++c) {
        const int k = r * cols + c;
        if (!(map.weight[k] > 0.0f) || scene.not_ring.data[k]) continue;
        // Keep the defect's faint rim out of its own reference.
        if (c >= box.c0 - guard && c <= box.c1 + guard && r >= box.r0 - guard && r <= box.r1 + guard)
          continue;
        // Residuals along the normal, as the deviation's: a pixel of a spike's steep
        // triangles is millimetres off in w but not along its normal.
        const double wk = map.weight[k] * static_cast<double>(map.cos_tilt[k]) * map.cos_tilt[k];
        const Vector6d b = basis(map.u[k], map.v[k]);
        N += wk * b * b.transpose();
        rhs += wk * map.w[k] * b;
        ring_ww += wk * static_cast<double>(map.w[k]) * map.w[k];
        // The same ring's departure from the global reference (0 where it has none).
        const float ref = scene.ref[static_cast<std::size_t>(k)];
        const double off = std::isfinite(ref) ? map.w[k] - ref : 0.0;
        rhs_off += wk * off * b;
        ring_off2 += wk * off * off;
        ++ring;
      }
    if (ring >= 20) {
      const Eigen::LDLT<Matrix6d> ldlt(N);
      if (ldlt.info() == Eigen::Success && ldlt.vectorD().minCoeff() > 1e-8 * N(0, 0)) {
        quad_ = ldlt.solve(rhs);
        quad_off_ = ldlt.solve(rhs_off);
        local_ = quad_.allFinite() && quad_off_.allFinite();
      }
    }
    if (!local_) return;
    // The ring's rms residual about its quadratic, against the map's deviation noise:
    // about 0.7 around a defect on a smooth panel, up to 3 with another defect's tail in
    // it, 3.7-8 on the strip between two rolled edges that no quadratic follows (measured
    // at 0.5 mm, 40 µm noise). Where the global reference follows the panel, the ring's
    // departure from it is smooth: the smaller of the two residuals counts.
    const auto rms_about = [&](const Vector6d& q, const Vector6d& r, double zz) {
      return std::sqrt(std::max(0.0, (zz - 2.0 * q.dot(r) + q.dot(N * q)) / N(0, 0)));
    };
    const double rms_own = rms_about(quad_, rhs, ring_ww), rms_off = rms_about(quad_off_, rhs_off, ring_off2);
    ring_rms_ = std::min(rms_own, rms_off);
    // The global reference with its correction where it describes the ring clearly
    // better than the ring's own quadratic (on a fender's side that was 40 µm off under
    // the apex).
    on_global_ = rms_off < 0.8 * rms_own;
  }

  // Whether the ring allowed a fit; without one, the global reference is used.
  bool local() const { return local_; }
  double ring_rms() const { return ring_rms_; }

  // The reference height w at map point (pu, pv), which lies in pixel k.
  double at(double pu, double pv, std::size_t k) const {
    if (!local_) return scene_.ref[k];
    return on_global_ ? global_at(pu, pv, k) + basis(pu, pv).dot(quad_off_) : basis(pu, pv).dot(quad_);
  }

 private:
  Vector6d basis(double pu, double pv) const {
    const double x = (pu - cu_) * sc_, y = (pv - cv_) * sc_;
    Vector6d b;
    b << 1, x, y, x * x, x * y, y * y;
    return b;
  }

  // The global reference at a point of pixel k: the pixel's own height, moved by the
  // reference's slope within the pixel. Beside a fold the pixel's height comes from the
  // fits on its side (reference_surface.h), which the blend of tile fits does not
  // follow (its slope there was 0.05 off: 25 µm across a pixel, and a dent 18 mm from
  // a fold read 10 % short); there the slope is the pixels' own around it.
  double global_at(double pu, double pv, std::size_t k) const {
    const HeightMap& map = scene_.map;
    const double ref = scene_.ref[k];
    if (pu == map.u[k] && pv == map.v[k]) return ref;
    const double blend_here = scene_.reference.height_at(map.u[k], map.v[k]);
    if (std::abs(ref - blend_here) < kSameHeight)
      return ref + scene_.reference.height_at(pu, pv) - blend_here;
    const int cols = map.cols, r = static_cast<int>(k) / cols, c = static_cast<int>(k) % cols;
    const auto slope = [&](int dr, int dc) {
      const int r0 = r - dr, c0 = c - dc, r1 = r + dr, c1 = c + dc;
      if (r0 < 0 || c0 < 0 || r1 >= map.rows || c1 >= cols) return 0.0;
      const std::size_t a = static_cast<std::size_t>(r0 * cols + c0),
                        b = static_cast<std::size_t>(r1 * cols + c1);
      if (!(map.weight[a] > 0.0f && map.weight[b] > 0.0f) || !std::isfinite(scene_.ref[a]) ||
          !std::isfinite(scene_.ref[b]))
        return 0.0;
      const double span = dc ? map.u[b] - map.u[a] : map.v[b] - map.v[a];
      return std::abs(span) > 0.25 * map.pixel ? (scene_.ref[b] - scene_.ref[a]) / span : 0.0;
    };
    return ref + slope(0, 1) * (pu - map.u[k]) + slope(1, 0) * (pv - map.v[k]);
  }

  const CandidateScene& scene_;
  double cu_ = 0.0, cv_ = 0.0, sc_ = 1.0;  // the basis' centre (m) and scale (1/m)
  Vector6d quad_ = Vector6d::Zero(), quad_off_ = Vector6d::Zero();
  bool local_ = false, on_global_ = false;
  double ring_rms_ = 0.0;
};

// The deviation from the local reference over the box, along the normal (NaN where none,
// and on spikes: they are never the peak and never measured).
class LocalDeviation {
 public:
  LocalDeviation(const CandidateScene& scene, const Box& box, const LocalReference& reference)
      : map_(scene.map),
        box_(box),
        dev_(static_cast<std::size_t>(box.width() * box.height()), std::numeric_limits<float>::quiet_NaN()) {
    const int cols = map_.cols;
    for (int r = box.br0; r <= box.br1; ++r)
      for (int c = box.bc0; c <= box.bc1; ++c) {
        const int k = r * cols + c;
        if (!(map_.weight[k] > 0.0f) || scene.spikes.data[k]) continue;
        const double refw = reference.at(map_.u[k], map_.v[k], static_cast<std::size_t>(k));
        if (std::isfinite(refw))
          dev_[box.index(r, c)] = static_cast<float>((map_.w[k] - refw) * map_.cos_tilt[k]);
      }
  }

  float at(int r, int c) const { return dev_[box_.index(r, c)]; }

  // The weighted 3 x 3 mean around (r, c) within the box (0 where none).
  double smooth(int r, int c) const {
    double s = 0.0, ws = 0.0;
    for (int dr = -1; dr <= 1; ++dr)
      for (int dc = -1; dc <= 1; ++dc) {
        const int rr = r + dr, cc = c + dc;
        if (!box_.contains(rr, cc)) continue;
        const float v = at(rr, cc);
        if (!std::isfinite(v)) continue;
        const double wk = map_.weight[static_cast<std::size_t>(rr * map_.cols + cc)];
        s += wk * v, ws += wk;
      }
    return ws > 0 ? s / ws : 0.0;
  }

 private:
  const HeightMap& map_;
  const Box& box_;
  std::vector<float> dev_;
};

// The region around the peak (8-connected, within the box) where the deviation keeps
// the peak's sign and at least half its size.
std::vector<std::int32_t> half_height_region(const HeightMap& map, const Box& box, std::int32_t peak,
                                             double peak_val, const auto& value_at) {
  const int cols = map.cols;
  const double sign = peak_val < 0 ? -1.0 : 1.0;
  std::vector<std::int32_t> half;
  std::vector<std::uint8_t> seen(static_cast<std::size_t>(box.width() * box.height()), 0);
  std::vector<std::int32_t> stack{peak};
  seen[box.index(peak / cols, peak % cols)] = 1;
  while (!stack.empty()) {
    const int k = stack.back();
    stack.pop_back();
    half.push_back(k);
    for (int dr = -1; dr <= 1; ++dr)
      for (int dc = -1; dc <= 1; ++dc) {
        const int rr = k / cols + dr, cc = k % cols + dc;
        if (!box.contains(rr, cc)) continue;
        auto& s = seen[box.index(rr, cc)];
        if (s) continue;
        s = 1;
        const double v = value_at(rr, cc);
        if (std::isfinite(v) && sign * v >= 0.5 * std::abs(peak_val)) stack.push_back(rr * cols + cc);
      }
  }
  return half;
}

// The vertex of an isotropic paraboloid fitted to the pixels' deviation within 'rad' of
// the peak; the peak's own value where the fit fails (see the body).
double paraboloid_height(const HeightMap& map, const Box& box, const LocalDeviation& dev, std::int32_t peak,
                         double peak_val, double rad, bool coarse) {
  const int cols = map.cols;
  const double h = map.pixel, sign = peak_val < 0 ? -1.0 : 1.0;
  double height = peak_val;
  const double pu = map.u[static_cast<std::size_t>(peak)], pv = map.v[static_cast<std::size_t>(peak)];
  Eigen::Matrix4d M = Eigen::Matrix4d::Zero();
  Eigen::Vector4d b = Eigen::Vector4d::Zero();
  int n = 0;
  const int rp = static_cast<int>(std::ceil(rad / h)) + 1;
  for (int r = std::max(box.br0, peak / cols - rp); r <= std::min(box.br1, peak / cols + rp); ++r)
    for (int c = std::max(box.bc0, peak % cols - rp); c <= std::min(box.bc1, peak % cols + rp); ++c) {
      const int k = r * cols + c;
      const float v = dev.at(r, c);
      if (!std::isfinite(v)) continue;
      const double x = (map.u[k] - pu) / rad, y = (map.v[k] - pv) / rad;
      if (x * x + y * y > 1.0) continue;
      const Eigen::Vector4d e(1, x, y, x * x + y * y);
      M += map.weight[k] * e * e.transpose();
      b += map.weight[k] * v * e;
      ++n;
    }
  if (n >= 6) {
    const Eigen::LDLT<Eigen::Matrix4d> l(M);
    const Eigen::Vector4d p = l.solve(b);
    if (l.info() == Eigen::Success && p.allFinite() && p(3) * sign < 0) {
      const double vx = -p(1) / (2 * p(3)), vy = -p(2) / (2 * p(3));
      if (vx * vx + vy * vy <= 1.0)
        height = p(0) - (p(1) * p(1) + p(2) * p(2)) / (4 * p(3));
      else
        height = p(0);
    } else if (l.info() == Eigen::Success && p.allFinite()) {
      height = p(0);
    }
  } else if (coarse) {
    height = dev.at(peak / cols, peak % cols);
  }
  return height;
}

// The apex height from the scan's own samples within 'rad' of the peak (apex_fit.h).
// The window is a disc of 'rad', or for a long apex an ellipse 'stretch' times as long
// along 'along'.
std::optional<double> sampled_apex_height(const CandidateScene& scene, const LocalReference& reference,
                                          std::int32_t peak, double rad, double sign,
                                          const Eigen::Vector2d& along, double stretch) {
  const HeightMap& map = scene.map;
  const int cols = map.cols;
  const double pu = map.u[static_cast<std::size_t>(peak)], pv = map.v[static_cast<std::size_t>(peak)];
  const int rp = static_cast<int>(std::ceil(stretch * rad / map.pixel)) + 1;
  std::vector<Eigen::Vector3d> pts;
  std::vector<ApexSample> near;
  for (int r = std::max(0, peak / cols - rp); r <= std::min(map.rows - 1, peak / cols + rp); ++r)
    for (int c = std::max(0, peak % cols - rp); c <= std::min(cols - 1, peak % cols + rp); ++c) {
      const int k = r * cols + c;
      if (!(map.weight[k] > 0.0f)) continue;
      pts.clear();
      scene.samples.append(k, pts);
      for (const auto& q : pts) {
        const double refw = reference.at(q.x(), q.y(), static_cast<std::size_t>(k));
        if (std::abs(q.z() - refw) > kFarSample) continue;  // seen past the panel
        near.push_back({q.x() - pu, q.y() - pv, (q.z() - refw) * map.cos_tilt[k]});
      }
    }
  return stretch > 1.0 ? fit_apex_height(near, rad, sign, along, stretch) : fit_apex_height(near, rad, sign);
}

// The apex window's shape from the half-height region's spread: a long region (a
// crease-shaped dent) gets an ellipse its own width across, at most kMaxStretch times as
// long; anything rounder the disc of its area.
struct ApexWindow {
  double radius = 0.0, stretch = 1.0;
  Eigen::Vector2d along = Eigen::Vector2d::UnitX();
};

ApexWindow apex_window(const HeightMap& map, const std::vector<std::int32_t>& half, double half_radius,
                       double min_radius) {
  constexpr double kLong = 2.0;  // semi-axes further apart than this: an ellipse
  constexpr double kMaxStretch = 4.0;
  ApexWindow w;
  w.radius = std::max(half_radius, min_radius);
  // Pixel centres (the region may hold empty pixels between samples).
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (auto k : half) mean += Eigen::Vector2d(k % map.cols, k / map.cols);
  mean /= static_cast<double>(half.size());
  Eigen::Matrix2d spread = Eigen::Matrix2d::Zero();
  for (auto k : half) {
    const Eigen::Vector2d d = Eigen::Vector2d(k % map.cols, k / map.cols) - mean;
    spread += d * d.transpose();
  }
  // Plus a pixel's own extent, so that a line one pixel wide has a width.
  spread = spread / static_cast<double>(half.size()) + Eigen::Matrix2d::Identity() / 12.0;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(spread);
  // A uniform ellipse of semi-axes a, b has variances a²/4, b²/4.
  const double across = 2.0 * std::sqrt(eig.eigenvalues()(0)) * map.pixel,
               along = 2.0 * std::sqrt(eig.eigenvalues()(1)) * map.pixel;
  if (along > kLong * across) {
    w.radius = std::max(across, min_radius);
    w.stretch = std::clamp(along / w.radius, 1.0, kMaxStretch);
    // Map columns are u, rows v.
    w.along = eig.eigenvectors().col(1);
  }
  return w;
}

}  // namespace

Measurement measure_candidate(const CandidateScene& scene, const std::vector<std::int32_t>& pixels, int label,
                              double length, const Eigen::Vector2d& mean) {
  const HeightMap& map = scene.map;
  const int cols = map.cols;
  const double h = map.pixel;
  const Box box = box_around(pixels, map, length);
  const LocalReference reference(scene, box, length, mean);
  const LocalDeviation dev(scene, box, reference);
  const auto value_at = [&](int r, int c) {
    return scene.coarse ? static_cast<double>(dev.at(r, c)) : dev.smooth(r, c);
  };
  Measurement m;
  m.rough_surroundings = reference.ring_rms() >
                         std::max(kRoughRing * scene.deviation_noise, kSmoothRingFloor * scene.min_height);
  // Peak: the candidate's pixel of largest smoothed |deviation| (raw on coarse maps).
  m.peak = pixels.front();
  for (auto k : pixels) {
    const double v = value_at(k / cols, k % cols);
    if (std::isfinite(v) && std::abs(v) > std::abs(m.peak_deviation)) m.peak_deviation = v, m.peak = k;
  }
  const double sign = m.peak_deviation < 0 ? -1.0 : 1.0;
  const std::vector<std::int32_t> half = half_height_region(map, box, m.peak, m.peak_deviation, value_at);
  m.half_radius = h * std::sqrt(static_cast<double>(half.size()) / std::numbers::pi);
  // Height: the vertex of a paraboloid over the pixels near the peak, then the same apex
  // from the vertices over the half-height disc. On coarse scans (a pixel of one or two
  // samples) a defect whose half-height radius spans fewer than 2.5 samples has too few
  // under its apex for a fit: its extreme vertex is taken below.
  m.height = paraboloid_height(map, box, dev, m.peak, m.peak_deviation,
                               std::max(1.5 * h, 0.5 * m.half_radius), scene.coarse);
  bool apex_fitted = false;
  if (!scene.coarse || m.half_radius >= 2.5 * scene.spacing) {
    const ApexWindow w = apex_window(map, half, m.half_radius, 2.5 * scene.spacing);
    if (const auto apex = sampled_apex_height(scene, reference, m.peak, w.radius, sign, w.along, w.stretch))
      m.height = *apex, apex_fitted = true;
  }
  // Position: the deviation-weighted centre of the half-height region, on the surface.
  double ws = 0.0;
  for (auto k : half) {
    const float v = dev.at(k / cols, k % cols);
    const double wk =
        map.weight[static_cast<std::size_t>(k)] * (std::isfinite(v) ? std::abs(v) : 0.0) + 1e-12;
    m.position += wk * Eigen::Vector3d(map.u[k], map.v[k], map.w[k]);
    ws += wk;
  }
  m.position /= ws;
  if (scene.coarse) {
    // A pixel spans several samples on a coarse scan and averages a narrow apex away:
    // the apex from the mesh vertices that fall in the candidate, unless fitted.
    // And whether one vertex alone stands out: among those within kSpikeReach pixels of
    // the candidate (an outlier's own pixel is a spike, left out of it; its triangles
    // raise the pixels around).
    constexpr int kSpikeReach = 2;
    int c0 = cols, c1 = 0, r0 = map.rows, r1 = 0;
    for (auto k : pixels)
      c0 = std::min(c0, k % cols), c1 = std::max(c1, k % cols), r0 = std::min(r0, k / cols),
      r1 = std::max(r1, k / cols);
    c0 -= kSpikeReach, r0 -= kSpikeReach, c1 += kSpikeReach, r1 += kSpikeReach;
    const int wide = c1 - c0 + 1;
    std::vector<std::uint8_t> reach(static_cast<std::size_t>(wide * (r1 - r0 + 1)), 0);
    for (auto k : pixels)
      for (int r = k / cols - kSpikeReach; r <= k / cols + kSpikeReach; ++r)
        for (int c = k % cols - kSpikeReach; c <= k % cols + kSpikeReach; ++c)
          reach[static_cast<std::size_t>((r - r0) * wide + c - c0)] = 1;
    double best = 0.0, best_near = 0.0, next_near = 0.0;  // extreme deviations (sign-wise)
    Eigen::Vector3d at_best = m.position;
    for (std::size_t i = 0; i < scene.mesh.vertex_count(); ++i) {
      const Eigen::Vector3d q = map.to_map(scene.mesh.vertex(i).cast<double>());
      const long k = map.pixel_of(q.x(), q.y());
      if (k < 0) continue;
      const int r = static_cast<int>(k / cols), c = static_cast<int>(k % cols);
      if (r < r0 || r > r1 || c < c0 || c > c1 || !reach[static_cast<std::size_t>((r - r0) * wide + c - c0)])
        continue;
      const double dv = sign * (q.z() - reference.at(q.x(), q.y(), static_cast<std::size_t>(k))) *
                        map.cos_tilt[static_cast<std::size_t>(k)];
      if (std::abs(dv) > kFarSample) continue;
      if (dv > best_near)
        next_near = best_near, best_near = dv;
      else if (dv > next_near)
        next_near = dv;
      if (scene.labels.at<int>(r, c) == label && dv > best) best = dv, at_best = q;
    }
    if (reference.local() && !apex_fitted) {
      m.position = at_best;
      if (best > std::abs(m.height)) m.height = sign * best;
    }
    // A defect, however narrow, lifts the samples around its apex too (the paper's 9 mm
    // bump at 4.5 mm spacing: 5.6 and 3.6 mm); a sample thrown off along its ray stands
    // alone (4 mm, the next 0.04 mm at 1.2 mm spacing).
    m.single_sample = best_near > kSingleSample * scene.deviation_noise && next_near < 0.5 * best_near;
  }
  // A candidate with no pixel measurable against a reference (spikes only, or beyond
  // every fit) has no height: it is noise, and no NaN reaches the output.
  if (!std::isfinite(m.height)) m.height = 0.0;
  return m;
}

}  // namespace dentmark::detect
