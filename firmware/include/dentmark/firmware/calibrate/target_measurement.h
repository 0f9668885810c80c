#pragma once
// One measurement of the tool's target by the stereo pair: the target found in both
// images (calibration_target.h), every corner triangulated into camL with the stereo
// calibration (track::triangulate: DLT refined on both cameras' reprojection error).
// A pose is usable only when every corner of the board is found in both images, so
// that all samples carry the same points (robot_fit.h).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "dentmark/common/geometry/transform.h"
#include "dentmark/firmware/calibrate/calibration_target.h"
#include "dentmark/firmware/track/stereo_calibration.h"

namespace dentmark::calibrate {

struct TargetMeasurement {
  bool found = false;
  std::string why;                                     // when not found
  std::vector<Eigen::Vector3d> points_camL;            // corner-id order
  std::vector<cv::Point2f> pixels_left, pixels_right;  // the corners found, corner-id order
  double max_reprojection_px = 0.0;                    // worst corner's triangulation residual
  // The board's pose from its triangulated corners (rigid fit to the board's own
  // coordinates): a first guess for planning, not used by the fit.
  Transform T_camL_target = Transform::Identity();
};

// A chessboard used as the robot's target must have COLS + ROWS odd (its orientation
// is read from the black square beyond corner 0). Throws CalibrateError otherwise.
void require_oriented_chessboard(const TargetSpec& target);

// max_reprojection_px: a corner triangulating worse than this (one camera matched the
// wrong corner) makes the pose unusable.
TargetMeasurement measure_target(const TargetSpec& target, const track::StereoCalibration& stereo,
                                 const cv::Mat& left, const cv::Mat& right, double max_reprojection_px = 2.0);

}  // namespace dentmark::calibrate
