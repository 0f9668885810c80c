#pragma once
// Grey images from files, by what the file holds (PNG or JPEG), not by its name.

#include <opencv2/core/mat.hpp>
#include <string>

#include "dentmark/common/image/png_io.h"  // ImageError

namespace dentmark::image {

// Reads a PNG or JPEG file as 8-bit grey (CV_8UC1). Throws ImageError naming the file
// when it cannot be read or holds neither.
cv::Mat read_grey_image(const std::string& path);

}  // namespace dentmark::image
