#pragma once
// The 13 real stereo chessboard pairs of Debian's opencv-doc (9x6 inner corners,
// 640x480, pairs 01–09 and 11–14; there is no pair 10), and OpenCV's own
// samples/cpp/stereo_calib.cpp procedure on them, reimplemented step by step as the
// reference our calibration must not be worse than.

#include <filesystem>
#include <string>
#include <vector>

namespace dentmark::calibrate::test {

// Debian installs the images uncompressed (.jpg, not .jpg.gz: dh_compress leaves
// images alone).
inline const std::filesystem::path kOpenCvData = "/usr/share/doc/opencv-doc/examples/data";
inline const std::vector<int> kOpenCvPairs = {1, 2, 3, 4, 5, 6, 7, 8, 9, 11, 12, 13, 14};

// "" when all 26 images are there, else what is missing (install opencv-doc:
// scripts/setup-deps).
std::string opencv_data_problem();

// Copies the pairs into 'dir' (created), as left<NN>.jpg / right<NN>.jpg.
void copy_opencv_pairs(const std::filesystem::path& dir);

struct SampleResult {
  int pairs = 0;      // pairs in which both images' corners were found
  double rms_px = 0;  // cv::stereoCalibrate's RMS
};

// stereo_calib.cpp (OpenCV 4.6) StereoCalib(): findChessboardCorners at scale 1 then 2
// (ADAPTIVE_THRESH | NORMALIZE_IMAGE), cornerSubPix 11x11 (30 iterations, 0.01),
// initCameraMatrix2D per camera, stereoCalibrate with FIX_ASPECT_RATIO |
// ZERO_TANGENT_DIST | USE_INTRINSIC_GUESS | SAME_FOCAL_LENGTH | RATIONAL_MODEL |
// FIX_K3 | FIX_K4 | FIX_K5, criteria (100, 1e-5).
SampleResult opencv_sample_stereo_calib(const std::vector<std::filesystem::path>& lefts,
                                        const std::vector<std::filesystem::path>& rights, double square_m);

}  // namespace dentmark::calibrate::test
