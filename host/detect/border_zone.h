#pragma once
// The map's surface near its outside: the panel's edges and openings (the window), where
// no reference surface can be trusted and a candidate belongs to the design.

#include <opencv2/core/mat.hpp>

#include "dentmark/host/detect/height_map.h"

namespace dentmark::detect {

// CV_8U, 255 on surface pixels within 3 mm (at least 2 pixels) of the outside: empty
// regions larger than a (10 mm)² dropout or touching the map's border. (A map from
// build_height_map has an empty ring of pixels round it, so the surface's own edge is
// always next to such a region.)
cv::Mat border_zone(const HeightMap& map);

}  // namespace dentmark::detect
