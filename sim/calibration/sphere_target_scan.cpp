#include "dentmark/sim/calibration/sphere_target_scan.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

namespace dentmark::sim::calibration {
namespace {

constexpr double kNone = std::numeric_limits<double>::infinity();

// Nearest positive ray parameter t of o + t d (|d| = 1) on a sphere.
double hit_sphere(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& c, double r) {
  const Eigen::Vector3d oc = o - c;
  const double b = oc.dot(d), q = oc.squaredNorm() - r * r, disc = b * b - q;
  if (disc < 0.0) return kNone;
  const double s = std::sqrt(disc);
  if (-b - s > 0.0) return -b - s;
  return -b + s > 0.0 ? -b + s : kNone;
}

// A stem: the cylinder of radius r about the board's z axis through (c.x, c.y), 0 ≤ z ≤ c.z
// (board frame; the ray is in the board frame too).
double hit_stem(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& c, double r) {
  const Eigen::Vector2d o2(o.x() - c.x(), o.y() - c.y()), d2(d.x(), d.y());
  const double a = d2.squaredNorm();
  if (a < 1e-15) return kNone;
  const double b = o2.dot(d2), q = o2.squaredNorm() - r * r, disc = b * b - a * q;
  if (disc < 0.0) return kNone;
  for (double t : {(-b - std::sqrt(disc)) / a, (-b + std::sqrt(disc)) / a}) {
    const double z = o.z() + t * d.z();
    if (t > 0.0 && z >= 0.0 && z <= c.z()) return t;
  }
  return kNone;
}

}  // namespace

SphereTarget twin_sphere_target() {
  SphereTarget t;
  t.spheres_board = {{-0.19, -0.12, 0.060},
                     {0.71, -0.06, 0.050},
                     {0.66, 0.36, 0.070},
                     {-0.17, 0.50, 0.045},
                     {0.17, 0.51, 0.065}};
  t.plate_min = Eigen::Vector2d(-0.24, -0.17);
  t.plate_max = Eigen::Vector2d(0.76, 0.56);
  return t;
}

std::vector<Eigen::Vector3f> scan_sphere_target(const SphereTarget& target, const Transform& T_sls_board,
                                                const SlsImaging& im) {
  const Transform T_board_sls = T_sls_board.inverse();
  // The ray grid spans the plate's outline as the sensor sees it (normalised x/z, y/z).
  Eigen::Vector2d lo(kNone, kNone), hi(-kNone, -kNone);
  double z_mean = 0.0;
  for (double x : {target.plate_min.x(), target.plate_max.x()})
    for (double y : {target.plate_min.y(), target.plate_max.y()}) {
      const Eigen::Vector3d p = T_sls_board * Eigen::Vector3d(x, y, 0.0);
      const Eigen::Vector2d n = p.head<2>() / p.z();
      lo = lo.cwiseMin(n), hi = hi.cwiseMax(n);
      z_mean += 0.25 * p.z();
    }
  const double step = im.spacing / z_mean;
  std::mt19937_64 rng(im.seed);
  std::normal_distribution<double> noise(0.0, im.range_noise);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Eigen::Vector3d o = T_board_sls.translation();  // the sensor in the board frame
  std::vector<Eigen::Vector3f> out;
  for (double v = lo.y() - step; v <= hi.y() + step; v += step)
    for (double u = lo.x() - step; u <= hi.x() + step; u += step) {
      const Eigen::Vector3d d_sls = Eigen::Vector3d(u, v, 1.0).normalized();
      const Eigen::Vector3d d = T_board_sls.linear() * d_sls;
      double t = kNone;
      if (std::abs(d.z()) > 1e-12) {  // the plate, z = 0
        const double tp = -o.z() / d.z();
        const Eigen::Vector3d p = o + tp * d;
        if (tp > 0.0 && p.x() >= target.plate_min.x() && p.x() <= target.plate_max.x() &&
            p.y() >= target.plate_min.y() && p.y() <= target.plate_max.y())
          t = tp;
      }
      for (const Eigen::Vector3d& c : target.spheres_board) {
        t = std::min(t, hit_sphere(o, d, c, target.sphere_radius));
        t = std::min(t, hit_stem(o, d, c, target.stem_radius));
      }
      if (t == kNone) continue;
      t += noise(rng);
      if (im.outlier_fraction > 0.0 && unit(rng) < im.outlier_fraction)
        t += (unit(rng) < 0.5 ? -1.0 : 1.0) * (0.002 + 0.018 * unit(rng));
      out.push_back((t * d_sls).cast<float>());
    }
  return out;
}

}  // namespace dentmark::sim::calibration
