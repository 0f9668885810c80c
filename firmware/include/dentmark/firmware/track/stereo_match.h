#pragma once
// Step A, camR → camL (paper §IV-A): the right-image corner is found in the left image
// by normalised cross-correlation along its epipolar curve (distortion-aware, over a
// depth range), then pyramidal LK camR → camL and sub-pixel refinement in camL by
// aligning the camR patch (template_align.h).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>

#include "dentmark/firmware/track/pyramid_lk.h"
#include "dentmark/firmware/track/stereo_calibration.h"

namespace dentmark::track {

struct StereoMatchOptions {
  double min_depth = 0.3;   // m
  double max_depth = 30.0;  // m
  int template_half = 10;   // px
  double min_ncc = 0.6;
};

struct StereoMatch {
  cv::Point2f left;
  double ncc = 0.0;
};

std::optional<StereoMatch> match_right_to_left(const StereoCalibration& calib, const ImagePyramid& right,
                                               const ImagePyramid& left, const cv::Point2f& p_right,
                                               const StereoMatchOptions& options, const LkOptions& lk);

// Refines the camL position of a matched feature by aligning the camR patch after
// mapping it into camL's view of the panel's local plane (unit normal n_camL through
// p_camL): the two cameras see a plane under different foreshortening (vergence, the
// panel's yaw), and a patch aligned by translation alone lands off the corner by a
// fraction of the neighbouring structure's apparent shift: 0.1-0.5 px of disparity,
// several mm of depth. Nothing when the patch leaves an image or the match is poor.
std::optional<StereoMatch> align_on_plane(const StereoCalibration& calib, const cv::Mat& right,
                                          const cv::Mat& left, const cv::Point2f& p_right,
                                          const cv::Point2f& p_left, const Eigen::Vector3d& p_camL,
                                          const Eigen::Vector3d& n_camL, const StereoMatchOptions& options);

}  // namespace dentmark::track
