#pragma once
// A finding's surface normal, as the marking side needs it: the least-squares plane over
// a square patch of the panel around it (30 mm by default), the finding itself left out.

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "dentmark/host/detect/height_map.h"

namespace dentmark::detect {

// The unit normal (scan frame) of the weighted least-squares plane through the map's
// pixels in a 'side' (m) square centred on pixel (row, col), pixels set in 'exclude'
// (CV_8U) left out; oriented towards the sensor. The map's w axis where fewer than three
// pixels remain or the fit fails.
Eigen::Vector3d patch_normal(const HeightMap& map, double side, int row, int col, const cv::Mat& exclude);

}  // namespace dentmark::detect
