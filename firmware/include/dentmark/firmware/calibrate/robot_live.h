#pragma once
// The live robot calibration and its check, on a TargetRig (robot_acquisition.h).
//
// calibrate_robot_live:
//   1. the target is measured at the robot's current pose (the operator has jogged it
//      so that both cameras see the target), which gives a first T_base_camL;
//   2. the poses are planned with it (calibration_poses.h);
//   3. the robot visits them and the target is measured at each (poses where it is not
//      found whole in both images are skipped and reported);
//   4. T_base_camL is fitted from those samples exactly as from a samples file
//      (robot_fit.h);
//   5. the robot returns to its start pose.
// verify_robot_live plans a few other poses from the stored T_base_camL, measures the
// target there and judges the stored transform (robot_verify.h).

#include <vector>

#include "dentmark/firmware/calibrate/calibration_poses.h"
#include "dentmark/firmware/calibrate/robot_acquisition.h"
#include "dentmark/firmware/calibrate/robot_verify.h"

namespace dentmark::calibrate {

struct LiveCalibration {
  Transform T_base_tool_start = Transform::Identity();
  Transform T_base_camL_prior = Transform::Identity();  // from the start pose alone
  std::vector<Transform> planned;
  Acquisition acquisition;
  RobotFit fit;
};

using PoseProgress = std::function<void(std::size_t, std::size_t, const PoseRecord&)>;

// Throws CalibrateError (target not seen at the start, too few poses found) and
// hal::RobotError / hal::CameraError from the devices.
LiveCalibration calibrate_robot_live(TargetRig& rig, const ToolTarget& target,
                                     const track::StereoCalibration& stereo, const PosePlanOptions& plan,
                                     const PoseProgress& progress = {});

struct LiveVerify {
  std::vector<Transform> planned;
  Acquisition acquisition;
  VerifyResult result;
};

LiveVerify verify_robot_live(TargetRig& rig, const ToolTarget& target, const track::StereoCalibration& stereo,
                             const Transform& T_base_camL, const PosePlanOptions& plan, double tolerance_m,
                             const PoseProgress& progress = {});

}  // namespace dentmark::calibrate
