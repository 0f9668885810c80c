#pragma once
// The ChArUco target's detector is a loadable module (dentmark-charuco.so, Debian
// package dentmark-edge-charuco). It needs OpenCV's aruco, which Debian 12 ships only
// in libopencv-contrib, together with Qt, GDAL, Tesseract and about 120 other
// packages that a box calibrated with chessboard targets never uses. The program
// loads the module the first time a ChArUco target is asked for.

#include <opencv2/core/mat.hpp>

#include "dentmark/firmware/calibrate/calibration_target.h"

namespace dentmark::calibrate {

// Changes whenever CharucoModule or the types it passes change: the module and the
// program are built from the same tree, and a module of another build is refused.
constexpr int kCharucoModuleAbi = 1;

// The module's entry points.
struct CharucoModule {
  int abi = 0;
  // OpenCV's predefined dictionary id for a name such as "DICT_5X5_100", or -1.
  int (*dictionary_id)(const char* name) = nullptr;
  // The number of markers in a dictionary.
  int (*dictionary_size)(int id) = nullptr;
  // Finds and refines the board's corners (detect_target's contract).
  Detection (*detect)(const TargetSpec& target, const cv::Mat& grey) = nullptr;
};

// The module exports extern "C" const CharucoModule* dentmark_charuco_module().
inline constexpr const char* kCharucoModuleSymbol = "dentmark_charuco_module";

// The module, loaded once: from $DENTMARK_CHARUCO_MODULE when set, else installed
// beside the program (<program folder>/../lib/dentmark-edge/dentmark-charuco.so),
// else from the build tree. Throws CalibrateError naming each place tried and why it
// failed, and the package that installs it.
const CharucoModule& charuco_module();

}  // namespace dentmark::calibrate
