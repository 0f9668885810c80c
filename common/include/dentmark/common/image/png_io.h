#pragma once
// PNG read and write (libpng), for camera frames and pictures.

#include <opencv2/core/mat.hpp>
#include <stdexcept>
#include <string>

namespace dentmark::image {

// A file that cannot be read or written; what() names the file and the problem.
class ImageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Reads a PNG as stored: grey → CV_8UC1 / CV_16UC1, colour → BGR CV_8UC3 / CV_16UC3.
// Palettes and sub-byte greys are expanded to 8 bits; alpha is dropped.
cv::Mat read_png(const std::string& path);

// Reads a PNG as 8-bit grey (CV_8UC1) whatever it stores: colour weighted 0.299 R +
// 0.587 G + 0.114 B and 16 bits cut to their high byte, as OpenCV's
// imread(IMREAD_GRAYSCALE) does (the same libpng calls).
cv::Mat read_png_grey(const std::string& path);

// Writes CV_8UC1, CV_8UC3 (BGR), CV_16UC1 or CV_16UC3 (BGR). compression: 0 (fastest,
// largest) to 9.
void write_png(const std::string& path, const cv::Mat& image, int compression = 3);

}  // namespace dentmark::image
