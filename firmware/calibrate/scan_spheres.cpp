#include "dentmark/firmware/calibrate/scan_spheres.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>
#include <unordered_map>

#include "dentmark/common/geometry/plane_fit.h"
#include "dentmark/common/nth_smallest.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"

namespace dentmark::calibrate {
namespace {

constexpr double kPlateBand = 0.002;     // m: plate points lie this close to its plane
constexpr double kStandOff = 0.003;      // m: sphere candidates stand this far in front of it
constexpr std::size_t kMinPlate = 1000;  // points
constexpr std::size_t kMinSphere = 30;   // points kept on a sphere
constexpr double kMaxSphereRms = 0.001;  // m
constexpr double kRadiusTolerance = 0.10;
constexpr double kRansacBand = 0.001;  // m about the nominal sphere
constexpr double kMinCoverage = 0.25;  // of the radius: the points' spread across the view

Plane find_plate(std::span<const Eigen::Vector3d> p, std::size_t& count) {
  std::mt19937_64 rng(12345);  // deterministic: the same scan gives the same result
  std::uniform_int_distribution<std::size_t> pick(0, p.size() - 1);
  Eigen::Vector3d best_n = Eigen::Vector3d::UnitZ(), best_o = Eigen::Vector3d::Zero();
  std::size_t best = 0;
  // Count inliers on a subsample; the winner is refitted on all points.
  const std::size_t step = std::max<std::size_t>(1, p.size() / 20000);
  for (int k = 0; k < 300; ++k) {
    const Eigen::Vector3d a = p[pick(rng)], b = p[pick(rng)], c = p[pick(rng)];
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.norm() < 1e-9) continue;
    n.normalize();
    std::size_t in = 0;
    for (std::size_t i = 0; i < p.size(); i += step) in += std::abs(n.dot(p[i] - a)) < kPlateBand;
    if (in > best) best = in, best_n = n, best_o = a;
  }
  std::vector<Eigen::Vector3d> plate;
  for (const Eigen::Vector3d& q : p)
    if (std::abs(best_n.dot(q - best_o)) < kPlateBand) plate.push_back(q);
  count = plate.size();
  if (plate.size() < kMinPlate) return {};
  Plane pl = fit_plane(plate);
  if (pl.normal.dot(-pl.centroid) < 0.0) pl.normal = -pl.normal;  // towards the sensor at the origin
  return pl;
}

// Connected clusters of points on a grid of 'cell' (26-neighbourhood). A cell with fewer
// than kMinCellPoints points is empty: sparse outliers in front of the plate would
// otherwise chain up into one cluster with the spheres.
constexpr std::size_t kMinCellPoints = 3;
std::vector<std::vector<Eigen::Vector3d>> clusters(const std::vector<Eigen::Vector3d>& p, double cell) {
  auto key = [](std::int64_t x, std::int64_t y, std::int64_t z) {
    return (static_cast<std::uint64_t>(x & 0x1fffff) << 42) |
           (static_cast<std::uint64_t>(y & 0x1fffff) << 21) | static_cast<std::uint64_t>(z & 0x1fffff);
  };
  std::unordered_map<std::uint64_t, std::vector<std::size_t>> grid;
  std::vector<std::array<std::int64_t, 3>> cells(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) {
    for (int k = 0; k < 3; ++k) cells[i][k] = static_cast<std::int64_t>(std::floor(p[i](k) / cell));
    grid[key(cells[i][0], cells[i][1], cells[i][2])].push_back(i);
  }
  std::erase_if(grid, [](const auto& kv) { return kv.second.size() < kMinCellPoints; });
  std::unordered_map<std::uint64_t, int> label;
  std::vector<std::vector<Eigen::Vector3d>> out;
  for (const auto& [k0, members] : grid) {
    if (label.count(k0)) continue;
    const int id = static_cast<int>(out.size());
    out.emplace_back();
    std::vector<std::array<std::int64_t, 3>> stack{cells[members.front()]};
    label[k0] = id;
    while (!stack.empty()) {
      const auto c = stack.back();
      stack.pop_back();
      for (std::size_t i : grid[key(c[0], c[1], c[2])]) out[id].push_back(p[i]);
      for (int dx = -1; dx <= 1; ++dx)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dz = -1; dz <= 1; ++dz) {
            const std::array<std::int64_t, 3> n{c[0] + dx, c[1] + dy, c[2] + dz};
            const std::uint64_t kn = key(n[0], n[1], n[2]);
            if (grid.count(kn) && !label.count(kn)) label[kn] = id, stack.push_back(n);
          }
    }
  }
  return out;
}

// Algebraic sphere: |p|² = 2 c·p + k, k = r² − |c|².
bool algebraic_sphere(const std::vector<Eigen::Vector3d>& p, Eigen::Vector3d& c, double& r) {
  Eigen::MatrixXd a(p.size(), 4);
  Eigen::VectorXd b(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) {
    a.row(static_cast<Eigen::Index>(i)) << 2.0 * p[i].x(), 2.0 * p[i].y(), 2.0 * p[i].z(), 1.0;
    b(static_cast<Eigen::Index>(i)) = p[i].squaredNorm();
  }
  const Eigen::Vector4d x = a.colPivHouseholderQr().solve(b);
  c = x.head<3>();
  const double r2 = x(3) + c.squaredNorm();
  if (!(r2 > 0.0) || !c.allFinite()) return false;
  r = std::sqrt(r2);
  return true;
}

// Centre of a sphere of radius r by Gauss-Newton on |p − c| − r.
Eigen::Vector3d fixed_radius_centre(const std::vector<Eigen::Vector3d>& p, double r, Eigen::Vector3d c) {
  for (int it = 0; it < 20; ++it) {
    Eigen::Matrix3d jtj = Eigen::Matrix3d::Zero();
    Eigen::Vector3d jtr = Eigen::Vector3d::Zero();
    for (const Eigen::Vector3d& q : p) {
      const Eigen::Vector3d d = q - c;
      const double n = d.norm();
      if (n < 1e-12) continue;
      const Eigen::Vector3d j = -d / n;  // ∂(|q − c| − r)/∂c
      jtj += j * j.transpose();
      jtr += j * (n - r);
    }
    const Eigen::Vector3d step = jtj.ldlt().solve(-jtr);
    if (!step.allFinite()) break;
    c += step;
    if (step.norm() < 1e-9) break;
  }
  return c;
}

double residual(const Eigen::Vector3d& q, const Eigen::Vector3d& c, double r) {
  return (q - c).norm() - r;
}

// A start for the fit that the stem and stray points cannot pull away: RANSAC over
// algebraic spheres through 4 random points of the cluster, keeping those with the
// nominal radius (within kRadiusTolerance), scored by the points within kRansacBand of
// the nominal sphere about their centre.
bool ransac_sphere(const std::vector<Eigen::Vector3d>& p, double r, Eigen::Vector3d& best_centre) {
  std::mt19937_64 rng(p.size());
  std::uniform_int_distribution<std::size_t> pick(0, p.size() - 1);
  std::size_t best = 0;
  for (int k = 0; k < 300; ++k) {
    const std::vector<Eigen::Vector3d> four{p[pick(rng)], p[pick(rng)], p[pick(rng)], p[pick(rng)]};
    Eigen::Vector3d c;
    double rr = 0.0;
    if (!algebraic_sphere(four, c, rr) || std::abs(rr - r) > kRadiusTolerance * r) continue;
    std::size_t in = 0;
    for (const Eigen::Vector3d& q : p) in += std::abs(residual(q, c, r)) < kRansacBand;
    if (in > best) best = in, best_centre = c;
  }
  return best >= kMinSphere;
}

std::string describe(const Eigen::Vector3d& c) {
  char b[80];
  std::snprintf(b, sizeof b, "cluster at (%.3f, %.3f, %.3f) m", c.x(), c.y(), c.z());
  return b;
}

// How far the points spread across the view: the smaller standard deviation of their
// projection onto the plane normal to the line of sight to the centre. The face of a
// ball seen from the sensor fills a disc of its radius (r/2 per axis); a ring of a stem
// that happens to lie on a sphere of the radius is narrow across.
double coverage(const std::vector<Eigen::Vector3d>& p, const Eigen::Vector3d& centre) {
  const Eigen::Vector3d view = centre.normalized();  // the sensor sits at the origin
  const Eigen::Vector3d a = view.unitOrthogonal(), b = view.cross(a);
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  std::vector<Eigen::Vector2d> q;
  for (const Eigen::Vector3d& x : p) q.emplace_back(a.dot(x - centre), b.dot(x - centre)), mean += q.back();
  mean /= static_cast<double>(q.size());
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (const Eigen::Vector2d& x : q) cov += (x - mean) * (x - mean).transpose();
  cov /= static_cast<double>(q.size());
  return std::sqrt(std::max(0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(cov).eigenvalues()(0)));
}

// One ball may fall into two clusters (its cap cut off from the rest by a shadowed band);
// both then fit it. Of spheres whose centres lie within a radius of each other the one
// with the most points is kept.
void merge_duplicates(std::vector<ScanSphere>& s) {
  std::sort(s.begin(), s.end(), [](const ScanSphere& a, const ScanSphere& b) { return a.points > b.points; });
  std::vector<ScanSphere> kept;
  for (const ScanSphere& x : s) {
    bool dup = false;
    for (const ScanSphere& k : kept) dup = dup || (k.centre_sls - x.centre_sls).norm() < k.radius_free_m;
    if (!dup) kept.push_back(x);
  }
  s = std::move(kept);
}

}  // namespace

ScanSpheres find_scan_spheres(std::span<const Eigen::Vector3d> all, double r) {
  std::vector<Eigen::Vector3d> p;
  p.reserve(all.size());
  for (const Eigen::Vector3d& q : all)
    if (q.allFinite()) p.push_back(q);
  ScanSpheres out;
  if (p.size() < kMinPlate)
    throw CalibrateError("the scan has " + std::to_string(p.size()) +
                         " usable points; the target needs more");
  const Plane plate = find_plate(p, out.plate_points);
  if (out.plate_points < kMinPlate)
    throw CalibrateError("no plate in the scan: no plane holds " + std::to_string(kMinPlate) +
                         " points within 2 mm (is the target in the scanner's view?)");
  out.plate_rms_m = plate.rms;
  std::vector<Eigen::Vector3d> proud;
  for (const Eigen::Vector3d& q : p) {
    const double h = plate.signed_distance(q);
    if (h > kStandOff && h < 0.5) proud.push_back(q);
  }
  for (std::vector<Eigen::Vector3d>& c : clusters(proud, 0.5 * r)) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& q : c) mean += q;
    mean /= static_cast<double>(std::max<std::size_t>(1, c.size()));
    if (c.size() < kMinSphere) {
      if (c.size() >= 10)
        out.rejected.push_back(describe(mean) + ": " + std::to_string(c.size()) + " points");
      continue;
    }
    Eigen::Vector3d centre;
    double r_free = 0.0;
    if (!ransac_sphere(c, r, centre)) {
      out.rejected.push_back(describe(mean) + ": no sphere of the target's radius in it");
      continue;
    }
    std::vector<Eigen::Vector3d> kept;
    for (int round = 0; round < 3; ++round) {
      std::vector<double> res;
      for (const auto& q : c) res.push_back(std::abs(residual(q, centre, r)));
      // Spread of the points near the sphere (the stem and the plate's edge are farther).
      std::vector<double> near;
      for (double e : res)
        if (e < kRansacBand) near.push_back(e);
      const double limit = std::max(3.0 * robust_sigma(near), 0.0003);
      kept.clear();
      for (std::size_t i = 0; i < c.size(); ++i)
        if (res[i] < limit) kept.push_back(c[i]);
      if (kept.size() < kMinSphere) break;
      centre = fixed_radius_centre(kept, r, centre);
    }
    if (kept.size() < kMinSphere) {
      out.rejected.push_back(describe(mean) + ": fewer than 30 points fit a sphere of the target's radius");
      continue;
    }
    centre = fixed_radius_centre(kept, r, centre);
    double ss = 0.0;
    for (const auto& q : kept) ss += std::pow(residual(q, centre, r), 2);
    const double rms = std::sqrt(ss / static_cast<double>(kept.size()));
    if (const double cover = coverage(kept, centre); cover < kMinCoverage * r) {
      char b[160];
      std::snprintf(b, sizeof b, ": its points span %.1f mm across the view, a ball's face %.1f mm (a stem?)",
                    cover * 1e3, 0.5 * r * 1e3);
      out.rejected.push_back(describe(mean) + b);
      continue;
    }
    Eigen::Vector3d c_free;
    if (!algebraic_sphere(kept, c_free, r_free) || std::abs(r_free - r) > kRadiusTolerance * r ||
        rms > kMaxSphereRms) {
      char b[160];
      std::snprintf(b, sizeof b, ": radius %.1f mm (nominal %.1f mm), RMS %.2f mm", r_free * 1e3, r * 1e3,
                    rms * 1e3);
      out.rejected.push_back(describe(mean) + b);
      continue;
    }
    out.spheres.push_back({centre, r_free, rms, kept.size()});
  }
  merge_duplicates(out.spheres);
  return out;
}

}  // namespace dentmark::calibrate
