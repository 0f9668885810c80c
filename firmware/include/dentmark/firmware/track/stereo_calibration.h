#pragma once
// The tracking pair's calibration (OpenCV stereoCalibrate conventions): intrinsics K,
// distortion D per camera and p_camR = R p_camL + T (metres). Projection, undistortion
// and two-view triangulation into camL, the tracker's reference frame.

#include <Eigen/Core>
#include <filesystem>
#include <opencv2/core.hpp>
#include <vector>

#include "dentmark/common/geometry/transform.h"

namespace dentmark::track {

enum class Cam { kLeft = 0, kRight = 1 };

struct CameraModel {
  cv::Matx33d K = cv::Matx33d::eye();
  cv::Mat D = cv::Mat::zeros(1, 5, CV_64F);
};

struct StereoCalibration {
  cv::Size size;
  CameraModel left, right;
  Transform T_camR_camL = Transform::Identity();

  const CameraModel& camera(Cam c) const { return c == Cam::kLeft ? left : right; }
  // Pixel positions of camL points as seen by camera c (with distortion).
  std::vector<cv::Point2f> project(Cam c, const std::vector<Eigen::Vector3d>& p_camL) const;
  // Undistorted normalised coordinates (x/z, y/z) of pixels of camera c.
  std::vector<cv::Point2d> normalize(Cam c, const std::vector<cv::Point2f>& pixels) const;
};

// Limits on the residuals a calibration file records (docs/calibration.md): a file
// over any of them is refused.
struct StereoResidualLimits {
  double max_rms_px = 1.0;       // rms_px: stereo RMS reprojection error
  double max_epipolar_px = 1.0;  // epipolar_rectified_px: mean |y_L − y_R| after rectification
  double max_holdout_px = 2.0;   // holdout_rms_px: error on views left out of the fit
};

// Reads stereo.yaml (image_width, image_height, K1, D1, K2, D2, R, T). R may be a 3x3
// matrix or a rotation vector; it must be orthonormal within 1e-3 with determinant +1.
// A file written by `dentmark-edge calibrate stereo` (field dentmark_stereo_calibration)
// must also carry rms_px, epipolar_rectified_px and holdout_rms_px within 'limits'
// (holdout_rms_px may be −1: not computed); in other files these fields are checked
// when present. Throws TrackError naming the file and field.
StereoCalibration load_stereo_calibration(const std::filesystem::path& path,
                                          const StereoResidualLimits& limits = {});

struct Triangulation {
  Eigen::Vector3d p_camL = Eigen::Vector3d::Zero();
  double reprojection_px = 0.0;  // larger of the two cameras' reprojection errors
};

// Linear (DLT) triangulation in normalised coordinates, refined by Gauss-Newton on the
// reprojection error of both cameras.
Triangulation triangulate(const StereoCalibration& calib, const cv::Point2d& n_left,
                          const cv::Point2d& n_right);

}  // namespace dentmark::track
