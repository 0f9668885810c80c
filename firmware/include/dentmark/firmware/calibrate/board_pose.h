#pragma once
// A planar target's pose from both cameras' corner pixels: the pose minimising the
// reprojection error of every corner in both images (Gauss-Newton on the undistorted
// normalised coordinates, weighted by each camera's focal length so that the residuals
// are pixels), started from the rigid fit of the triangulated corners
// (target_measurement.h). At the station's 2.8 m the triangulated corners are noisy
// along the viewing rays (depth) and precise across them; the rigid fit weighs both
// alike, the reprojection error weighs each direction by what the cameras resolve. The
// scanner calibration (scanner_calibration.h) carries sphere centres up to 0.4 m from
// the board's centre through this pose: its tilt matters.

#include <opencv2/core.hpp>
#include <vector>

#include "dentmark/common/geometry/transform.h"
#include "dentmark/firmware/calibrate/calibration_target.h"
#include "dentmark/firmware/track/stereo_calibration.h"

namespace dentmark::calibrate {

struct BoardPose {
  Transform T_camL_target = Transform::Identity();
  double rms_px = 0.0;  // RMS reprojection error over both cameras' corners
};

// pixels_left/right: every corner of 'target', in corner-id order.
BoardPose refine_board_pose(const TargetSpec& target, const track::StereoCalibration& stereo,
                            const std::vector<cv::Point2f>& pixels_left,
                            const std::vector<cv::Point2f>& pixels_right,
                            const Transform& T_camL_target_start);

}  // namespace dentmark::calibrate
