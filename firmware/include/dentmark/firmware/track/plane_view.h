#pragma once
// How a small patch of the panel's plane looks from a camera: the local affine map
// between two views of it (other camera, later pose), which the templates are
// resampled through (template_align.h: affine_patch) so that matching by translation
// stays on the same physical point although the views foreshorten it differently.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>
#include <span>

#include "dentmark/firmware/track/stereo_calibration.h"

namespace dentmark::track {

// Unit normal of the least-squares plane through the points; nothing when they are
// fewer than 3 or (nearly) collinear.
std::optional<Eigen::Vector3d> plane_normal(std::span<const Eigen::Vector3d> points);

// Pixels of camera `to_cam` per pixel of camera `from_cam` around the plane point
// x_camL (normal n_camL), the plane moved by `motion` (camL) between the two views.
// Nothing when the plane is seen edge-on.
std::optional<cv::Matx22d> plane_view_change(const StereoCalibration& calib, const Eigen::Vector3d& x_camL,
                                             const Eigen::Vector3d& n_camL, Cam from_cam, Cam to_cam,
                                             const Transform& motion = Transform::Identity());

}  // namespace dentmark::track
