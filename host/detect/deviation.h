#pragma once
// The height map's deviation from a robust reference surface (docs/detection.md §6).
// The reference is fitted, the pixels that stand out of it at any detection scale (and
// those found off the skin: outlier spikes, a hole's backdrop) are left out, and it is
// fitted again, cfg.reference_iterations times in all. Thresholds adapt to the noise
// measured on the deviation itself.

#include <opencv2/core/mat.hpp>
#include <vector>

#include "dentmark/host/detect/config.h"
#include "dentmark/host/detect/height_map.h"
#include "dentmark/host/detect/reference_surface.h"

namespace dentmark::detect {

// The detection scales for a map of this pixel size (m): box sides of 3, 7 and 15 mm in
// pixels, odd and distinct, for dents of 5 mm and up.
std::vector<int> detection_scales(double pixel);

// The robust sigma (1.4826 MAD about the median) of the finite values (CV_32F) on the
// pixels set in select (CV_8U), from ~60 000 of them taken at a fixed stride; 0 with
// under 10.
double sampled_robust_sigma(const cv::Mat& values, const cv::Mat& select);

struct Deviation {
  cv::Mat along_normal;             // CV_32F: from the reference along the normal (m), NaN where none
  cv::Mat candidates;               // CV_8U: 255 where some scale's box mean is over its threshold
  cv::Mat spikes;                   // CV_8U: 255 on outlier spikes and thrown clusters
  cv::Mat median_spikes;            // CV_8U: 255 on those of the 3 x 3 median test alone
  double noise = 0.0;               // robust sigma of along_normal over the interior (m)
  std::vector<double> scale_sigma;  // per scale: robust sigma of its box mean (m)
};

// interior: CV_8U, non-zero on the pixels whose statistics set the thresholds (away
// from borders and openings). 'reference' is left holding the last fit.
// keep_border_candidates (a chart's map): candidates reaching the border stay in the refits.
Deviation deviation_from_reference(const HeightMap& map, ReferenceSurface& reference, const cv::Mat& interior,
                                   const std::vector<int>& scales, const DetectConfig& cfg,
                                   bool keep_border_candidates);

}  // namespace dentmark::detect
