#pragma once
// Point-to-point motion with bounded speed and acceleration: the trapezoidal velocity
// profile (accelerate at a_max, cruise at v_max, decelerate at a_max; a triangle when
// the distance is too short to reach v_max). Closed form, so the simulated tool's
// position at any instant does not depend on how often the simulator steps.

namespace dentmark::sim::robot {

class TrapezoidProfile {
 public:
  TrapezoidProfile() = default;
  // distance >= 0, v_max > 0, a_max > 0 (std::invalid_argument otherwise).
  TrapezoidProfile(double distance, double v_max, double a_max);

  double duration() const { return duration_; }
  double peak_speed() const { return v_peak_; }
  // Distance covered at time t after the start (clamped to [0, duration]).
  double position(double t) const;
  double speed(double t) const;

 private:
  double distance_ = 0.0;
  double a_ = 1.0;
  double v_peak_ = 0.0;
  double t_ramp_ = 0.0;  // time to reach v_peak
  double duration_ = 0.0;
};

}  // namespace dentmark::sim::robot
