#pragma once
// Left/right image pairs in a folder.
//
// Naming: left<N>.<ext> and right<N>.<ext>, N one or more decimal digits, ext one of
// png, jpg, jpeg, bmp, tif, tiff (any case), as OpenCV's stereo samples name them
// (left01.jpg … right14.jpg). A pair is the left and right image with the same number
// N (compared as numbers: left1 pairs with right01). Other files are ignored. A
// numbered image without its partner, a number used twice on one side, or a folder
// with no pair is an error.

#include <filesystem>
#include <string>
#include <vector>

namespace dentmark::calibrate {

struct ImagePair {
  long number = 0;   // N
  std::string name;  // N as written in the left file's name ("01")
  std::filesystem::path left, right;
};

// Pairs sorted by N. Throws CalibrateError naming the folder or the unpaired file.
std::vector<ImagePair> find_image_pairs(const std::filesystem::path& dir);

}  // namespace dentmark::calibrate
