#pragma once
// Per-pixel ray tracing of the scene (scene.h) through one distorted camera (lens.h):
// the linear RGB irradiance of each pixel, integrated over the pixel's area and the
// exposure time. Every pixel gets one ray through its centre; a pixel whose corners do
// not all see the same region at the start and the end of the exposure (an edge, a
// corner, the arm's outline; widened by one pixel) is supersampled on an n x n grid
// instead (n-rooks: no two sub-rays share a row or a column), each sub-ray at its own
// time within the exposure (motion blur).

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "dentmark/sim/stereo_raytrace/lens.h"
#include "dentmark/sim/stereo_raytrace/scene.h"

namespace dentmark::sim::raytrace {

// Light on the panel, fixed in the station: irradiance at a camL point relative to the
// centre of the view, a linear gradient across the station.
struct Lighting {
  double level = 1.0;
  Eigen::Vector3d gradient{0.22, -0.12, 0.0};  // relative change per metre (camL x, y, z)
  Eigen::Vector3d centre{0.25, 0.2, 2.8};      // camL, m
  double at(const Eigen::Vector3d& p_camL) const { return level * (1.0 + gradient.dot(p_camL - centre)); }
};

class RayTracer {
 public:
  // T_camL_cam: the camera's pose in camL (identity for camL).
  RayTracer(BrownConrady lens, Eigen::Isometry3d T_camL_cam, cv::Size size, int supersample);

  // Panel poses T_camL_panel at evenly spaced instants across the exposure (one or more).
  // The supersampling grid's n * n sub-rays are spread over them (n not a multiple of 37).
  cv::Mat3f render(const Door& door, const std::optional<Arm>& arm,
                   const std::vector<Eigen::Isometry3d>& poses, const Lighting& light) const;

  const BrownConrady& lens() const { return lens_; }
  // Undistorted normalised coordinates of the pixel corner (u - 0.5, v - 0.5).
  const cv::Mat2d& corner_rays() const { return corners_; }

 private:
  BrownConrady lens_;
  Eigen::Isometry3d T_camL_cam_;
  cv::Size size_;
  int n_;
  cv::Mat2d corners_;  // (H + 1) x (W + 1)
};

}  // namespace dentmark::sim::raytrace
