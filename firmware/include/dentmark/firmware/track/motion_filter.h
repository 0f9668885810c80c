#pragma once
// Constant-velocity filter of the panel's motion M(t) with timestamps. Each of the six
// pose coordinates (rotation vector and translation, taken about the features' centroid
// so they are nearly uncorrelated) has a position-velocity Kalman filter. A measurement
// that disagrees with the prediction beyond a gate (the line stopped, jerked or was
// bumped) restarts that coordinate from the measurements, so the filter never lags a
// real change of motion; between such events it averages the measurement noise away.

#include <Eigen/Core>
#include <array>

#include "dentmark/common/geometry/transform.h"

namespace dentmark::track {

struct MotionFilterOptions {
  double accel_noise_translation = 0.003;  // m/s^2/sqrt(Hz): how hard a smooth line may accelerate
  // A conveyor carries the panel along a line without turning it: the rotation only
  // shakes with the line's vibration, so rotation is averaged over many frames (the
  // per-frame rotation is the least certain part of a stereo fit of a wide, short
  // feature layout: its depth noise levers onto the whole panel).
  double accel_noise_rotation = 3e-4;  // rad/s^2/sqrt(Hz)
  double gate_sigmas = 4.0;
  bool enabled = true;
};

class MotionFilter {
 public:
  MotionFilter(const Eigen::Vector3d& centre, const MotionFilterOptions& options);

  // Starts at M(t0) = identity.
  void reset(double t0);
  // The motion predicted at time t (constant velocity); does not change the state.
  Transform predict(double t) const;
  // Folds in a measured motion at t with per-coordinate standard deviations
  // (rotation rad, translation m); returns the filtered motion.
  Transform update(double t, const Transform& measured, const Eigen::Vector3d& sigma_rotation,
                   const Eigen::Vector3d& sigma_translation);
  // Posterior variance of each coordinate (rotation vector about the centre, rad²;
  // translation of the centre, m²).
  Eigen::Matrix<double, 6, 1> variance() const;
  // Number of gate restarts so far (for diagnostics).
  int restarts() const { return restarts_; }
  // M as (rotation vector, translation of the centre) and back.
  Eigen::Matrix<double, 6, 1> to_params(const Transform& m) const;
  Transform from_params(const Eigen::Matrix<double, 6, 1>& p) const;

 private:
  struct Axis {
    double x = 0.0, v = 0.0;
    double p00 = 0.0, p01 = 0.0, p11 = 0.0;
    double last_z = 0.0, last_t = 0.0;
    bool fresh = true;  // no velocity known yet
  };
  Eigen::Vector3d centre_;
  MotionFilterOptions options_;
  std::array<Axis, 6> axes_{};
  double t_ = 0.0;
  int restarts_ = 0;
};

}  // namespace dentmark::track
