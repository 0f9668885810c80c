#pragma once
// A camera with Brown-Conrady lens distortion (radial k1, k2, k3; tangential p1, p2;
// the order OpenCV's calibration writes them), for the ray-traced stereo renderer.
// Written independently of sim/stereo: pixel rays come from a Newton inversion of the
// distortion, not from OpenCV.

#include <Eigen/Core>
#include <array>

namespace dentmark::sim::raytrace {

struct BrownConrady {
  double fx = 1740.0, fy = 1740.0, cx = 640.0, cy = 512.0;
  std::array<double, 5> d{0, 0, 0, 0, 0};  // k1, k2, p1, p2, k3

  // Undistorted normalised coordinates (x/z, y/z) to pixels.
  Eigen::Vector2d project_normalized(const Eigen::Vector2d& xy) const;
  // Pixels to undistorted normalised coordinates (Newton on the distortion, to 1e-12).
  Eigen::Vector2d unproject(const Eigen::Vector2d& pixel) const;
  // The distortion alone: undistorted to distorted normalised coordinates.
  Eigen::Vector2d distort(const Eigen::Vector2d& xy) const;
};

}  // namespace dentmark::sim::raytrace
