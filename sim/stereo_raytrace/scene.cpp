#include "dentmark/sim/stereo_raytrace/scene.h"

#include <Eigen/Geometry>
#include <cmath>

namespace dentmark::sim::raytrace {
namespace {

// Crossing-number test.
bool inside(const std::vector<Eigen::Vector2d>& poly, const Eigen::Vector2d& p) {
  bool in = false;
  for (std::size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const Eigen::Vector2d& a = poly[i];
    const Eigen::Vector2d& b = poly[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) &&
        p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x())
      in = !in;
  }
  return in;
}

// Ray parameter of the nearest hit on the capped cylinder, or < 0.
double hit_arm(const Arm& arm, const Eigen::Vector3d& o, const Eigen::Vector3d& d, Eigen::Vector3d& normal) {
  const Eigen::Vector3d axis = (arm.b - arm.a).normalized();
  const double len = (arm.b - arm.a).norm();
  const Eigen::Vector3d oc = o - arm.a;
  const Eigen::Vector3d dp = d - d.dot(axis) * axis, op = oc - oc.dot(axis) * axis;
  const double qa = dp.squaredNorm(), qb = 2.0 * dp.dot(op), qc = op.squaredNorm() - arm.radius * arm.radius;
  const double disc = qb * qb - 4.0 * qa * qc;
  if (qa < 1e-18 || disc < 0.0) return -1.0;
  const double s = (-qb - std::sqrt(disc)) / (2.0 * qa);
  if (s <= 0.0) return -1.0;
  const Eigen::Vector3d p = oc + s * d;
  const double along = p.dot(axis);
  if (along < 0.0 || along > len) return -1.0;
  normal = (p - along * axis).normalized();
  return s;
}

}  // namespace

Door make_door() {
  using V = Eigen::Vector2d;
  Door door;
  door.background = {0.10f, 0.11f, 0.12f};
  // Skin: silver-blue paint.
  door.regions.push_back(
      {{V(-0.58, -0.55), V(0.58, -0.55), V(0.60, 0.58), V(-0.58, 0.58)}, {0.50f, 0.55f, 0.62f}});
  // Window frame (black rubber seal) and the glass inside it.
  const std::vector<V> frame = {V(-0.53, -0.05), V(-0.53, -0.22), V(-0.33, -0.47), V(0.47, -0.47),
                                V(0.51, -0.05)};
  const std::vector<V> glass = {V(-0.495, -0.085), V(-0.495, -0.208), V(-0.315, -0.435), V(0.438, -0.435),
                                V(0.473, -0.085)};
  door.regions.push_back({frame, {0.04f, 0.04f, 0.045f}});
  door.regions.push_back({glass, {0.20f, 0.24f, 0.26f}});
  // A crease below the window and the handle recess: structure that is not a feature.
  door.regions.push_back(
      {{V(-0.56, 0.12), V(0.57, 0.10), V(0.57, 0.112), V(-0.56, 0.134)}, {0.36f, 0.40f, 0.46f}});
  door.regions.push_back(
      {{V(0.25, 0.18), V(0.40, 0.18), V(0.40, 0.215), V(0.25, 0.215)}, {0.12f, 0.13f, 0.14f}});
  door.features = frame;
  door.features.insert(door.features.end(), glass.begin(), glass.end());
  for (double y : {0.22, 0.34, 0.46})
    for (double x : {-0.44, -0.14, 0.16, 0.44}) door.eval_points.emplace_back(x, y);
  return door;
}

Hit trace(const Door& door, const std::optional<Arm>& arm, const Eigen::Vector3d& origin,
          const Eigen::Vector3d& direction) {
  Hit h;
  double s_door = -1.0;
  if (std::abs(direction.z()) > 1e-15) s_door = -origin.z() / direction.z();
  if (arm) {
    Eigen::Vector3d n;
    const double s = hit_arm(*arm, origin, direction, n);
    if (s > 0.0 && (s_door <= 0.0 || s < s_door)) {
      h.region = 1000;
      h.reflectance = arm->reflectance;
      h.point = origin + s * direction;
      h.shading = static_cast<float>(0.25 + 0.75 * std::abs(n.dot(direction.normalized())));
      return h;
    }
  }
  h.reflectance = door.background;
  if (s_door <= 0.0) return h;
  h.point = origin + s_door * direction;
  const Eigen::Vector2d p = h.point.head<2>();
  for (int i = static_cast<int>(door.regions.size()) - 1; i >= 0; --i)
    if (inside(door.regions[static_cast<std::size_t>(i)].outline, p)) {
      h.region = i;
      h.reflectance = door.regions[static_cast<std::size_t>(i)].reflectance;
      break;
    }
  return h;
}

}  // namespace dentmark::sim::raytrace
