#include "dentmark/sim/stereo/panel_motion.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace dentmark::sim::stereo {

double PanelMotion::travel(double t) const {
  if (stop_at < 0.0 || t <= stop_at) return speed * t;
  const double moving = t - std::min(t, stop_at + stop_for);
  return speed * (stop_at + moving) - (t >= stop_at + stop_for ? reverse_jerk : 0.0);
}

Transform PanelMotion::T_camL_panel(double t) const {
  constexpr double kTwoPi = 2.0 * std::numbers::pi;
  // Conveyor vibration: a few incommensurate tones, well inside a real line's spectrum.
  const Eigen::Vector3d shake =
      vibration * Eigen::Vector3d(std::sin(kTwoPi * 2.3 * t), 0.7 * std::sin(kTwoPi * 3.7 * t + 1.0),
                                  0.5 * std::sin(kTwoPi * 1.3 * t + 2.0));
  const Eigen::Vector3d wobble =
      (vibration / 0.5) * Eigen::Vector3d(std::sin(kTwoPi * 1.7 * t), std::sin(kTwoPi * 2.9 * t + 0.5),
                                          std::sin(kTwoPi * 0.9 * t + 1.0));
  Transform m = Transform::Identity();
  m.translation() = travel(t) * direction + shake;
  const double angle = wobble.norm();
  if (angle > 0.0) m.linear() = Eigen::AngleAxisd(angle, wobble / angle).toRotationMatrix();
  // Vibration rotates about the panel's own centre, not camL's origin.
  Transform about_centre = Transform::Identity();
  about_centre.translation() = T_camL_panel0.translation();
  return Transform(Eigen::Translation3d(m.translation())) * about_centre * Transform(m.linear()) *
         about_centre.inverse() * T_camL_panel0;
}

}  // namespace dentmark::sim::stereo
