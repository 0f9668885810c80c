#include "dentmark/sim/robot/trapezoid_profile.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace dentmark::sim::robot {

TrapezoidProfile::TrapezoidProfile(double distance, double v_max, double a_max)
    : distance_(distance), a_(a_max) {
  if (!(distance >= 0.0) || !(v_max > 0.0) || !(a_max > 0.0) || !std::isfinite(distance) ||
      !std::isfinite(v_max) || !std::isfinite(a_max))
    throw std::invalid_argument("TrapezoidProfile: need distance >= 0, v_max > 0, a_max > 0");
  // Triangle when accelerating to v_max and back would overshoot: v_peak = sqrt(a d).
  v_peak_ = std::min(v_max, std::sqrt(a_max * distance));
  t_ramp_ = v_peak_ / a_max;
  const double d_ramps = v_peak_ * t_ramp_;  // both ramps together
  duration_ = v_peak_ > 0.0 ? 2.0 * t_ramp_ + (distance - d_ramps) / v_peak_ : 0.0;
}

double TrapezoidProfile::position(double t) const {
  if (t <= 0.0) return 0.0;
  if (t >= duration_) return distance_;
  if (t < t_ramp_) return 0.5 * a_ * t * t;
  const double t_decel = duration_ - t_ramp_;
  if (t <= t_decel) return 0.5 * a_ * t_ramp_ * t_ramp_ + v_peak_ * (t - t_ramp_);
  const double left = duration_ - t;
  return distance_ - 0.5 * a_ * left * left;
}

double TrapezoidProfile::speed(double t) const {
  if (t <= 0.0 || t >= duration_) return 0.0;
  if (t < t_ramp_) return a_ * t;
  if (t <= duration_ - t_ramp_) return v_peak_;
  return a_ * (duration_ - t);
}

}  // namespace dentmark::sim::robot
