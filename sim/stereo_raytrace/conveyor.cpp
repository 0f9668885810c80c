#include "dentmark/sim/stereo_raytrace/conveyor.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace dentmark::sim::raytrace {

double Conveyor::travel(double t) const {
  if (stop_at < 0.0 || t <= stop_at) return speed * t;
  // Speed profile: v until stop_at, linear down to 0 over `ramp`, rest for stop_for,
  // linear back up to v over `ramp`. Integrated in closed form piece by piece.
  const double r = std::max(ramp, 1e-9);
  double s = speed * stop_at;
  const double t1 = std::min(t - stop_at, r);  // decelerating
  s += speed * (t1 - 0.5 * t1 * t1 / r);
  if (t <= stop_at + r + stop_for) return s;
  const double t3 = std::min(t - (stop_at + r + stop_for), r);  // accelerating
  s += 0.5 * speed * t3 * t3 / r;
  const double t4 = t - (stop_at + 2 * r + stop_for);  // full speed again
  if (t4 > 0.0) s += speed * t4;
  return s;
}

Eigen::Isometry3d Conveyor::T_camL_panel(double t) const {
  constexpr double k2Pi = 2.0 * std::numbers::pi;
  const Eigen::Vector3d shake =
      vibration * Eigen::Vector3d(std::sin(k2Pi * 3.1 * t + 0.3), 0.6 * std::sin(k2Pi * 4.3 * t + 1.7),
                                  0.8 * std::sin(k2Pi * 1.9 * t + 2.2));
  const Eigen::Vector3d wobble =
      (vibration / 0.6) * Eigen::Vector3d(std::sin(k2Pi * 2.1 * t + 0.9), std::sin(k2Pi * 1.1 * t + 0.2),
                                          std::sin(k2Pi * 3.3 * t + 1.4));
  const double angle = wobble.norm();
  const Eigen::Matrix3d r =
      angle > 0.0 ? Eigen::AngleAxisd(angle, wobble / angle).toRotationMatrix() : Eigen::Matrix3d::Identity();
  // The wobble turns the panel about its own centre.
  Eigen::Isometry3d pose = T_camL_panel0;
  pose.linear() = Eigen::AngleAxisd(turn_rate * t, Eigen::Vector3d::UnitY()).toRotationMatrix() * r *
                  T_camL_panel0.linear();
  pose.translation() = T_camL_panel0.translation() + travel(t) * direction + shake;
  return pose;
}

}  // namespace dentmark::sim::raytrace
