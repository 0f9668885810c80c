#pragma once
// The tracking stereo pair as the renderer sees it (design.md §2: camL, camR) and its
// OpenCV FileStorage form, the `stereo.yaml` of a sequence directory.

#include <filesystem>
#include <opencv2/core.hpp>

#include "dentmark/common/geometry/transform.h"

namespace dentmark::sim::stereo {

struct PinholeCamera {
  cv::Matx33d K = cv::Matx33d::eye();
  cv::Mat D = cv::Mat::zeros(1, 5, CV_64F);  // OpenCV (k1, k2, p1, p2, k3)
};

struct StereoRig {
  cv::Size size{1280, 1024};
  PinholeCamera left, right;
  // p_camR = T_camR_camL * p_camL (OpenCV's R, T of stereoCalibrate), metres.
  Transform T_camR_camL = Transform::Identity();
};

// A horizontal pair: camR sits baseline_m along camL's +x and is turned toe_in_rad
// about y towards camL's axis, so both look at a point in front of the pair.
// k1 is the radial distortion given to both cameras (0: none).
StereoRig make_rig(cv::Size size, double focal_px, double baseline_m, double toe_in_rad, double k1 = 0.0);

// Every pixel's undistorted, normalised image coordinates (x/z, y/z) through 'cam':
// a size.height × size.width CV_32FC2 map, for renderers that cast a ray per pixel.
cv::Mat normalized_pixel_grid(const PinholeCamera& cam, cv::Size size);

// The sensor's last stage for a rendered irradiance image (grey levels, float): optical
// blur (Gaussian, sigma in px; 0: none), additive Gaussian noise (grey levels; 0: none),
// then 8-bit with saturation.
cv::Mat expose_8bit(cv::Mat1f image, double blur_sigma, double noise_sigma, cv::RNG& rng);

// Writes image_width, image_height, K1, D1, K2, D2, R, T as OpenCV FileStorage YAML.
void write_stereo_yaml(const StereoRig& rig, const std::filesystem::path& path);

}  // namespace dentmark::sim::stereo
