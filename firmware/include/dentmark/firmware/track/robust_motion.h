#pragma once
// Step B of paper §IV-A made robust: the rigid motion of the reference layout onto the
// current 3D features (Arun's least squares via dentmark::fit_rigid), started from the
// least-median-of-squares minimal sample and polished by iteratively reweighted least
// squares (Tukey's biweight), so occluded or mistracked features fall out.

#include <Eigen/Core>
#include <span>
#include <vector>

#include "dentmark/common/geometry/transform.h"

namespace dentmark::track {

struct RobustMotionOptions {
  double noise_floor = 2e-4;  // m: residual scale never assumed below this
  double outlier_sigmas = 3.5;
};

struct RobustMotion {
  Transform T_to_from = Transform::Identity();
  std::vector<bool> inlier;
  int inliers = 0;
  double rms = 0.0;    // weighted RMS residual of the inliers, m
  double scale = 0.0;  // robust residual scale, m
};

// from/to: corresponding points; prior weights may be empty. Throws GeometryError when
// fewer than 3 non-collinear points agree.
RobustMotion fit_rigid_robust(std::span<const Eigen::Vector3d> from, std::span<const Eigen::Vector3d> to,
                              std::span<const double> prior_weights, const RobustMotionOptions& options);

}  // namespace dentmark::track
