#pragma once
// Robot-to-stereo calibration (T_base_camL, the paper's Q_CB) from recorded samples: a
// target carried by the tool, whose points are known in the tool frame (from the
// mount's drawing), triangulated by the stereo pair at each robot pose.
//
//   p_base = T_base_tool,i · p_tool,j   (robot's pose i, target point j)
//   p_camL = the triangulated point j at pose i
//   T_base_camL = argmin Σ |p_base − T · p_camL|²   (Arun, Huang, Blostein 1987, with
//                 Umeyama's reflection fix: common/geometry/rigid_fit.h)
//
// Cross-check: cv::calibrateRobotWorldHandEye (Shah 2013) solves the same chain
// without the mount's drawing, from the target's pose in camL at each sample: the
// target plays the camera on the gripper and camL the world, so its "base to world"
// is T_camL_base and its "gripper to camera" T_target_tool (the identity when the
// drawing is right). Hold-out: each pose in turn left out of the rigid fit, its points
// transferred into base and compared with the robot's.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "dentmark/common/geometry/transform.h"

namespace dentmark::calibrate {

struct RobotSample {
  Transform T_base_tool = Transform::Identity();  // as the robot reports it
  std::vector<Eigen::Vector3d> points_camL;       // triangulated, in target_points_tool's order
};

struct RobotSamples {
  std::vector<Eigen::Vector3d> target_points_tool;  // the target's points in the tool frame, metres
  std::vector<RobotSample> samples;
};

struct RobotFit {
  Transform T_base_camL = Transform::Identity();
  double rms_m = 0.0;                                     // point residual RMS of the fit (3D)
  double holdout_rms_m = 0.0;                             // leave-one-pose-out point transfer RMS (3D)
  double holdout_max_pose_m = 0.0;                        // the worst held-out pose's RMS
  std::vector<double> holdout_pose_rms_m;                 // per pose
  Transform T_base_camL_handeye = Transform::Identity();  // cross-check
  double handeye_translation_diff_m = 0.0;
  double handeye_rotation_diff_rad = 0.0;
  Transform T_target_tool_handeye = Transform::Identity();  // the mount as the hand-eye solution sees it
};

// Throws CalibrateError: fewer than 3 poses or 3 target points, point counts that
// differ from the target's, non-finite values, a pose that is not rigid, or
// degenerate geometry (all points collinear).
RobotFit fit_robot(const RobotSamples& samples);

}  // namespace dentmark::calibrate
