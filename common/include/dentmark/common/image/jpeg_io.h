#pragma once
// JPEG read (libjpeg-turbo), for calibration images such as the stereo chessboard
// pairs of Debian's opencv-doc.

#include <opencv2/core/mat.hpp>
#include <string>

#include "dentmark/common/image/png_io.h"  // ImageError

namespace dentmark::image {

// Reads a baseline or progressive JPEG as 8-bit grey (CV_8UC1): libjpeg's own colour
// conversion with its default (islow) DCT, as OpenCV's imread(IMREAD_GRAYSCALE) does.
cv::Mat read_jpeg_grey(const std::string& path);

}  // namespace dentmark::image
