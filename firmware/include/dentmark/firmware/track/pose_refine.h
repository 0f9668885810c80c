#pragma once
// Polishes the rigid motion by Gauss-Newton on the reprojection error of the reference
// features in both cameras (Huber-weighted). A 3D fit weighs the triangulated points
// isotropically although their depth is 5-10x less certain than their lateral
// position; the image residuals carry the true error structure.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

#include "dentmark/firmware/track/stereo_calibration.h"

namespace dentmark::track {

struct PoseRefineResult {
  Transform motion = Transform::Identity();
  double rms_px = 0.0;  // reprojection RMS over both cameras
  // Σ JᵀJ at the result, per px² of image noise, for the left perturbation
  // M → exp(δω) M + δt, parameters (δω, δt): the inverse, times the pixel noise
  // variance, is the motion's covariance.
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
};

// reference: camL points at the first frame; n_left / n_right: their undistorted
// normalised observations now (same order). Returns the refined M.
PoseRefineResult refine_pose(const StereoCalibration& calib, const Transform& start,
                             const std::vector<Eigen::Vector3d>& reference,
                             const std::vector<cv::Point2d>& n_left, const std::vector<cv::Point2d>& n_right,
                             int iterations = 5, double huber_px = 1.0);

}  // namespace dentmark::track
