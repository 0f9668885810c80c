#pragma once
// The robot calibration's target: a printed chessboard or ChArUco board
// (calibration_target.h) fixed to the tool flange. Its pose in the tool frame,
// T_tool_target, comes from the mount's drawing; the target's corner j lies at
// T_tool_target · spec.corner(j) in the tool frame.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "dentmark/common/geometry/transform.h"
#include "dentmark/firmware/calibrate/calibration_target.h"

namespace dentmark::calibrate {

struct ToolTarget {
  TargetSpec spec;
  Transform T_tool_target = Transform::Identity();

  // Every corner of the board in the tool frame, in corner-id order (metres).
  std::vector<Eigen::Vector3d> points_tool() const;
};

// Parses "x y z rx ry rz" (metres, rotation vector in radians) into T_tool_target.
// Throws CalibrateError naming 'option'.
Transform parse_pose6(const std::vector<double>& values, const std::string& option);

}  // namespace dentmark::calibrate
