#pragma once
// Stereo calibration from a folder of image pairs: reads the pairs (image_pairs.h),
// finds the target in every image (calibration_target.h), keeps the corners both
// cameras saw, fits (stereo_fit.h) and records where the result came from.

#include <filesystem>
#include <string>
#include <vector>

#include "dentmark/firmware/calibrate/calibration_target.h"
#include "dentmark/firmware/calibrate/image_pairs.h"
#include "dentmark/firmware/calibrate/stereo_fit.h"

namespace dentmark::calibrate {

struct StereoCalibrationRun {
  TargetSpec target;
  std::vector<ImagePair> pairs;
  StereoFit fit;
  // One entry per pair, in order: the fit's figures, or why the pair was not used
  // ("left: no 9x6 chessboard found", an outlier rule).
  std::vector<ViewFigures> views;
  std::string inputs_sha256;  // input_digest.h over the target description and every image
  std::string created_utc;    // ISO 8601, e.g. 2026-12-05T19:30:00Z
  std::string tool_version;   // dentmark::kVersion
};

// Throws CalibrateError: no pairs, an unpaired or unreadable image, images of
// different sizes (naming the file), or too few pairs with the target in both images.
StereoCalibrationRun calibrate_stereo_images(const std::filesystem::path& dir, const TargetSpec& target,
                                             const StereoFitOptions& options = {});

// The StereoView of one pair: corners found in both images, matched by id. A
// chessboard found from opposite ends in the two images (first-to-last corner
// directions more than 90° apart) has its right corners reversed.
StereoView stereo_view(const TargetSpec& target, const std::string& name, const Detection& left,
                       const Detection& right);

}  // namespace dentmark::calibrate
