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

// Reads stereo.yaml (image_width, image_height, K1, D1, K2, D2, R, T). R may be a 3x3
// matrix or a rotation vector. Throws TrackError naming the file and field.
StereoCalibration load_stereo_calibration(const std::filesystem::path& path);

struct Triangulation {
  Eigen::Vector3d p_camL = Eigen::Vector3d::Zero();
  double reprojection_px = 0.0;  // larger of the two cameras' reprojection errors
};

// Linear (DLT) triangulation in normalised coordinates, refined by Gauss-Newton on the
// reprojection error of both cameras.
Triangulation triangulate(const StereoCalibration& calib, const cv::Point2d& n_left,
                          const cv::Point2d& n_right);

}  // namespace dentmark::track
