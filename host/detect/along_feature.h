#pragma once
// Defects on and beside a design feature that runs along a line: a character line, a
// crease, a rolled edge, a handle's long side (docs/detection.md §7).
//
// A reference surface cannot follow such a feature: it leaves a band in the deviation in
// which a dent beside the line merges with the line's own candidate and is taken for part
// of the design. Along the line the surface is smooth, a defect is not. So each pixel near
// the feature is compared with the surface's own profile along the line, from the map's
// heights and not from the reference, whose errors along a smooth step come in blocks:
//  - heights at the pixels' centres (a quadric through the 3 x 3 mean points), since on a
//    line's steep flank a pixel's mean point alone is off by up to a sixth of a pixel, and
//    on its curved shoulders a plane through them is off by tens of micrometres;
//  - no height where a sample was thrown (the deviation's spikes, and pixels off their
//    neighbours' plane): a flying pixel moves its pixel's mean point by millimetres;
//  - the direction across the dominant gradient of less noisy heights (3 x 3 planes),
//    less the panel's own slope over 20 mm (the structure tensor over 6 mm), refined to
//    a quarter degree to where the profile fits best;
//  - the profile: a quadratic in the distance along the line through the heights 13-45 mm
//    ahead and behind (the panel's slope and curvature along the line), fitted twice,
//    leaving out samples past 3 sigma; it is uncertain by 4 times the fit's spread or by
//    how far apart the two flanks' own lines pass the pixel, whichever is larger (a
//    handle's end, a line that stops);
//  - both flanks seen and reaching out (no profile extrapolated from one side);
//  - walls (slope over 0.8 less the panel's: a handle's sides and ends) neither looked
//    at nor in a profile;
//  - where no direction dominates, the deviation itself, except within 35 mm of the
//    border zone (the border's own band, judged by the design rules).
// Candidates pass the detection scales' thresholds (from the residual's own noise, which
// neighbouring pixels share), the profile's uncertainty, and detection_sigma times the
// residual's spread along the line through them (a steep flank's small errors repeat
// with the pixel grid's phase). A defect in a pixel's flanks leaves a ghost of the other
// sign 13-45 mm along the line each side of it, so the search runs twice, the first
// run's findings (and its pieces too narrow to report) left out of the second's flanks,
// and its findings out of the direction round them.
//
// Off by default (DetectConfig::along_features): it finds most defects beside and on
// features, but raises false alarms (0.1-0.3 per m², 4.9 with flying pixels; see
// docs/detection.md §12).

#include <opencv2/core/mat.hpp>
#include <vector>

#include "dentmark/host/detect/config.h"
#include "dentmark/host/detect/detector.h"
#include "dentmark/host/detect/height_map.h"

namespace dentmark::detect {

// The heights (CV_32F, m, at the pixels' centres; NaN where none) less their profile
// along the feature (residual, along the normal), on the pixels set in zone (CV_8U),
// the feature's direction read from steer (heights of the same kind);
// where no direction dominates, dev (CV_32F deviation, m) instead; NaN elsewhere, and
// where either flank has under 60 % of its samples seen. Pixels set in blocked (CV_8U)
// are never flank samples; those set in undirecting (CV_8U, may be empty) have no say
// in the direction of the feature round them.
struct AlongFeature {
  cv::Mat residual;     // CV_32F, m
  cv::Mat uncertainty;  // CV_32F, m: how far off the profile may be at the pixel
  cv::Mat angle;        // CV_32F: the feature's direction (rad, in the map's column-row plane); NaN: none
  cv::Mat wall;         // CV_8U: walls (a handle's sides and ends), grown over their rounded rims
};
AlongFeature along_feature_residual(const HeightMap& map, const cv::Mat& height, const cv::Mat& steer,
                                    const cv::Mat& dev, const cv::Mat& zone, const cv::Mat& blocked,
                                    const cv::Mat& undirecting);

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
