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
//
// The same minimisation over several views of the target, each at a known pose in a
// frame x (T_x_target, e.g. the board in the scanner's frame from the scanned
// spheres), solves for the one transform T_camL_x shared by all views: every corner of
// every view projected through T_camL_x · T_x_target. That is the maximum-likelihood
// T_camL_x when the corners' pixel noise dominates and T_x_target is known much better
// than the cameras fix the board (scanner_fit.h).

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

// One view of the target: its corners in both images (corner-id order, every corner)
// and the target's pose in the frame x.
struct BoardView {
  std::vector<cv::Point2f> pixels_left, pixels_right;
  Transform T_x_target = Transform::Identity();
};

struct ChainedPose {
  Transform T_camL_x = Transform::Identity();
  double rms_px = 0.0;  // RMS reprojection error over every view's corners in both cameras
};

// T_camL_x minimising the reprojection error of all views' corners, from 'start'.
ChainedPose refine_chained_pose(const TargetSpec& target, const track::StereoCalibration& stereo,
                                const std::vector<BoardView>& views, const Transform& T_camL_x_start);

}  // namespace dentmark::calibrate
