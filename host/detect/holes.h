#pragma once
// Holes (a class the paper lists but does not detect): a region of the height map that is
// enclosed by surface and where the scanner saw through the skin, i.e. the surface is
// missing there and what was measured lies far behind it. A region with no data at all
// is a dropout (a specular or dark spot) or a hole with nothing behind it: the scan alone
// cannot tell, so it is not reported as a hole.

#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "dentmark/host/detect/height_map.h"

namespace dentmark::detect {

struct HoleRegion {
  std::vector<std::int32_t> pixels;     // gap and see-through pixels
  int behind = 0;                       // points seen through it
  double diameter = 0.0;                // m, equivalent (area) diameter
  double backdrop_depth = 0.0;          // m, median depth of what was seen through it
  std::vector<std::int32_t> seen_deep;  // deep pixels elsewhere whose points were seen through it
};

// A candidate is a connected region of pixels without skin (empty, or whose front lies
// more than behind_depth behind the reference 'ref'), not touching the map's edge, no wider
// than max_diameter, ringed by skin. It is a hole when points behind the skin (the map's
// 'behind' leaves and its deep pixels), traced back along their sensor ray to the
// reference, pass through it: at least 3, and a tenth of its pixels.
// deviation: per pixel (CV_32F, NaN where no surface), m along the normal.
std::vector<HoleRegion> find_holes(const HeightMap& map, const cv::Mat& deviation,
                                   const std::vector<float>& ref, double behind_depth, double max_diameter);

}  // namespace dentmark::detect
