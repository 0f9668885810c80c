#pragma once
// Acquires a taught panel model (panel_model.h) in a stereo frame without seeds:
// 1. each feature's coarsest template is searched over the whole coarsest pyramid level
//    of both images (normalised cross-correlation, a few best peaks each), the peaks are
//    followed down the pyramid with the finer templates and fitted to a sub-pixel peak;
// 2. left and right candidates of a feature pair up when they triangulate (epipolar
//    consistency, depth in front of the pair);
// 3. the candidate set is verified against the taught 3D layout, RANSAC-like: every
//    three features whose candidates keep the taught pairwise distances give a rigid
//    motion (Arun), which must bring most of the other taught features onto one of
//    their candidates. Without such a consensus the panel is not there: no lock.
// The camR positions of the consensus then seed Tracker::start (the seed path refines
// them like an operator's clicks).

#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "dentmark/firmware/track/panel_model.h"
#include "dentmark/firmware/track/stereo_calibration.h"

namespace dentmark::track {

struct ModelSearchOptions {
  int peaks = 5;                  // candidates kept per feature and camera at the coarsest level
  double min_coarse_ncc = 0.5;    // at the coarsest level
  double min_ncc = 0.6;           // at level 0
  double max_reprojection = 2.0;  // px: a left/right pair must triangulate this well
  // Agreement with the taught layout: max(min_tolerance, sigmas × the depth error of
  // match_noise px of disparity at the features' depth).
  double min_tolerance = 0.005;  // m
  double match_noise = 0.25;     // px
  double sigmas = 4.0;
  double min_share = 0.6;  // of the taught features must agree (and at least 4)
};

struct ModelSearchResult {
  // Per taught feature: its camR position when it is part of the consensus.
  std::vector<std::optional<cv::Point2f>> seeds_right;
  int found = 0;                                   // features in the consensus
  Transform T_now_taught = Transform::Identity();  // taught layout → this frame, camL
  double rms = 0.0;                                // 3D residual of the consensus, m
};

// Throws TrackError (without a file name: the caller adds it) when the model is not
// found: too few features agree with the taught layout.
ModelSearchResult search_model(const StereoCalibration& calib, const cv::Mat& left, const cv::Mat& right,
                               const PanelModel& model, const ModelSearchOptions& options = {});

}  // namespace dentmark::track
