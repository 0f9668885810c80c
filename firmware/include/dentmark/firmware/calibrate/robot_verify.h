#pragma once
// `dentmark-edge calibrate verify`: does the stored T_base_camL still hold? The target
// is re-measured at a few poses (other than the calibration's) and each measured point
// transferred into base with the stored transform and compared with where the robot
// says it is: the same point transfer the calibration's hold-out figure reports. It
// holds when every planned pose showed the target (a camera knocked out of line loses
// it) and the RMS transfer error is within the board's calibration.verify_tolerance.

#include <string>
#include <vector>

#include "dentmark/common/geometry/transform.h"
#include "dentmark/firmware/calibrate/robot_fit.h"

namespace dentmark::calibrate {

struct VerifyResult {
  bool holds = false;
  std::string reason;  // when it does not hold
  int poses_planned = 0;
  int poses_measured = 0;
  double rms_m = 0.0;       // point transfer RMS over all measured poses (3D)
  double max_pose_m = 0.0;  // the worst pose's RMS
  std::vector<double> pose_rms_m;
  double tolerance_m = 0.0;
};

VerifyResult verify_robot_calibration(const RobotSamples& measured, const Transform& T_base_camL,
                                      int poses_planned, double tolerance_m);

}  // namespace dentmark::calibrate
