#pragma once
// The stereo.yaml that `dentmark-edge calibrate stereo` writes (OpenCV FileStorage
// YAML): what the tracker reads (track::load_stereo_calibration: image_width,
// image_height, K1 D1 K2 D2 R T), then the figures that say how good it is and where
// it came from. docs/calibration.md lists every field.

#include <string>

#include "dentmark/firmware/calibrate/stereo_from_images.h"

namespace dentmark::calibrate {

// Format tag and version written as `dentmark_stereo_calibration`.
inline constexpr int kStereoFileVersion = 1;

// The file's text.
std::string stereo_calibration_yaml(const StereoCalibrationRun& run);
// The same figures as one JSON object (for --json).
std::string stereo_calibration_json(const StereoCalibrationRun& run);
// Writes stereo_calibration_yaml atomically (common/atomic_file.h). Throws CalibrateError.
void write_stereo_calibration(const std::string& path, const StereoCalibrationRun& run);

}  // namespace dentmark::calibrate
