#pragma once
// The replay format of a recorded or rendered stereo sequence (a directory):
//   stereo.yaml  calibration (see stereo_calibration.h)
//   frames.csv   header `index,t,left,right`; image paths relative to the directory
//   seeds.yaml   seeds_right: N x 2 rough pixel positions of the macro-features in the
//                right image of the first frame

#include <filesystem>
#include <opencv2/core.hpp>
#include <vector>

#include "dentmark/firmware/track/stereo_calibration.h"

namespace dentmark::track {

struct FrameEntry {
  long index = 0;
  double t = 0.0;  // s, strictly increasing
  std::filesystem::path left, right;
};

struct Sequence {
  std::filesystem::path dir;
  StereoCalibration calibration;
  std::vector<FrameEntry> frames;
};

// Reads stereo.yaml and frames.csv. Throws TrackError naming the file and line.
Sequence load_sequence(const std::filesystem::path& dir);

// Reads seeds.yaml (seeds_right, N x 2) and checks every seed lies inside the image.
std::vector<cv::Point2f> load_seeds(const std::filesystem::path& path, cv::Size image_size);

// Reads an image as 8-bit grey (colour is converted) and checks its size.
cv::Mat load_grey(const std::filesystem::path& path, cv::Size expected);

}  // namespace dentmark::track
