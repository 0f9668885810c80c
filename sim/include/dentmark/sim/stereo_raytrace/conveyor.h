#pragma once
// The door's motion on the conveyor for the ray-traced renderer: along a straight line
// at a set speed, with a little vibration, and optionally a stop: the line decelerates
// and accelerates at a finite rate (ramp seconds from full speed to rest).

#include <Eigen/Geometry>

namespace dentmark::sim::raytrace {

struct Conveyor {
  Eigen::Isometry3d T_camL_panel0 = Eigen::Isometry3d::Identity();  // pose at t = 0
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();             // unit, camL
  double speed = 0.014;                                             // m/s
  double vibration = 8e-5;  // m amplitude (and vibration / 0.6 m rad of wobble)
  double stop_at = -1.0;    // s the deceleration starts; < 0: never
  double stop_for = 0.0;    // s at rest
  double ramp = 0.15;       // s from full speed to rest and back
  double turn_rate = 0.0;   // rad/s about camL y through the panel's origin (0: a plain line)

  double travel(double t) const;  // m along the line
  Eigen::Isometry3d T_camL_panel(double t) const;
  // M(t) = T_camL_panel(t) T_camL_panel(0)^-1: camL at t = 0 to camL at t.
  Eigen::Isometry3d motion(double t) const { return T_camL_panel(t) * T_camL_panel(0.0).inverse(); }
};

}  // namespace dentmark::sim::raytrace
