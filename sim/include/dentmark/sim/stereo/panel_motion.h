#pragma once
// The panel's pose on the conveyor over time, with small vibration and optional
// line stops: the ground truth of the tracker (design.md §2, M(t)).

#include <Eigen/Core>

#include "dentmark/common/geometry/transform.h"

namespace dentmark::sim::stereo {

struct PanelMotion {
  Transform T_camL_panel0 = Transform::Identity();       // pose at t = 0
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();  // conveyor direction in camL, unit
  double speed = 0.014;                                  // m/s
  double vibration = 1e-4;    // translation amplitude, m (rotation: vibration / 0.5 m rad)
  double stop_at = -1.0;      // s; < 0: the line never stops
  double stop_for = 0.0;      // s the line stands still
  double reverse_jerk = 0.0;  // m the line jumps back when it restarts (0: none)

  // Distance travelled along the conveyor at t, metres.
  double travel(double t) const;
  // Pose of the panel in camL at t.
  Transform T_camL_panel(double t) const;
  // M(t): camL coordinates at t = 0 to camL coordinates at t.
  Transform motion(double t) const { return T_camL_panel(t) * T_camL_panel(0.0).inverse(); }
};

}  // namespace dentmark::sim::stereo
