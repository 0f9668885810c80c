#pragma once
// Defects on and beside a design feature that runs along a line: a character line, a
// crease, a rolled edge, a handle's long side (docs/detection.md §7).
//
// A reference surface cannot follow such a feature: it leaves a band in the deviation in
// which a dent beside the line merges with the line's own candidate and is taken for part
// of the design. The band is the same all along the line, a defect is not. So each pixel
// near the feature takes out the deviation's own profile along the line: the mean of the
// medians of the deviation 13-45 mm ahead of it and 13-45 mm behind it. The direction is
// across the deviation's dominant gradient (its structure tensor over 6 mm), refined to a
// quarter degree where ahead and behind agree best; where the gradients have no dominant
// direction there is no line and nothing is taken out. Candidates are thresholded at the
// detection scales' thresholds and at 4 times the flanks' own spread.
//
// Off by default (DetectConfig::along_features): the reference leaves blocks and streaks
// along a smooth step, which come out of this as false alarms (docs/detection.md §12).

#include <opencv2/core/mat.hpp>
#include <vector>

#include "dentmark/host/detect/config.h"
#include "dentmark/host/detect/detector.h"
#include "dentmark/host/detect/height_map.h"

namespace dentmark::detect {

// The deviation dev (CV_32F, m, NaN where none) with the profile along the feature taken
// out (residual), and how much the flanks spread about their medians (spread: 1.4826 x
// their median absolute offset), on the pixels set in zone (CV_8U); NaN elsewhere, and
// where either flank has under 60 % of its samples. pixel: the map's pixel size (m).
struct AlongFeature {
  cv::Mat residual, spread;  // CV_32F, m
  cv::Mat angle;  // CV_32F: the feature's direction (rad, in the map's column-row plane); NaN: none
};
AlongFeature along_feature_residual(const HeightMap& map, const cv::Mat& dev, const cv::Mat& zone,
                                    const cv::Mat& blocked);

// What the scene around a design feature offers the search for local defects.
struct AlongFeatureScene {
  const HeightMap& map;
  const cv::Mat& dev;                       // CV_32F deviation along the normal (m)
  const cv::Mat& design;                    // CV_8U: pixels of the design candidates (where to look round)
  const cv::Mat& edge_zone;                 // CV_8U: the map's border zone
  const cv::Mat& excluded;                  // CV_8U: holes, spikes: never part of a defect
  const cv::Mat& not_surface;               // CV_8U: left out of the normals' plane fits
  const std::vector<std::int32_t>& labels;  // the detection's labels so far (>= 0: a reported defect)
  const std::vector<int>& scales;           // box sides (pixels)
  const std::vector<double>& scale_sigma;
  double sigma3 = 0.0;  // deviation noise of the finest scale (m)
};

// Dents and bumps within 30 mm of a design feature that stand out of the feature's
// profile along it at some detection scale (the thresholds of deviation.h) and have the
// shape of a defect (design_rules.h), away from defects already reported. Each comes with
// its pixels in 'pixels'.
std::vector<Finding> defects_along_features(const AlongFeatureScene& scene, const DetectConfig& cfg,
                                            std::vector<std::vector<std::int32_t>>& pixels);

}  // namespace dentmark::detect
