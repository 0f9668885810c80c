#pragma once
// The printed calibration target and its detection in one image.
//
// Two kinds:
//   chessboard:COLSxROWS  COLS × ROWS inner corners (OpenCV's convention: a 9x6
//                         board has 10 × 7 squares). Every corner must be found.
//   charuco:COLSxROWS     COLS × ROWS squares with ArUco markers in the white ones
//                         (OpenCV aruco module); any subset of its (COLS−1)(ROWS−1)
//                         inner corners may be found, each carries its id.
// Corners are refined to sub-pixel accuracy (cornerSubPix). Object points lie in the
// board's plane z = 0, in metres, with corner (i, j) at (i·square, j·square).

#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace dentmark::calibrate {

enum class TargetKind { kChessboard, kCharuco };

struct TargetSpec {
  TargetKind kind = TargetKind::kChessboard;
  int cols = 0;            // chessboard: inner corners across; charuco: squares across
  int rows = 0;            // chessboard: inner corners down;   charuco: squares down
  double square_m = 0.0;   // side of one square, metres
  double marker_m = 0.0;   // charuco: side of one marker, metres
  std::string dictionary;  // charuco: OpenCV predefined dictionary name, e.g. DICT_5X5_100
  int dictionary_id = -1;  // its cv::aruco::PREDEFINED_DICTIONARY_NAME value

  // Number of corners a full view of the board yields.
  int corner_count() const;
  // Board coordinates (metres, z = 0) of the corner with this id (row-major index).
  cv::Point3f corner(int id) const;
  // "chessboard:9x6 square 0.025 m" — for reports.
  std::string describe() const;
};

// Parses --pattern ("chessboard:9x6" or "charuco:COLSxROWS") with --square, --marker
// and --dictionary. Throws CalibrateError naming the option.
TargetSpec parse_target(const std::string& pattern, double square_m, double marker_m,
                        const std::string& dictionary);

struct Detection {
  bool found = false;
  std::vector<cv::Point2f> corners;  // sub-pixel refined, pixels
  std::vector<int> ids;              // corner ids (chessboard: 0 … n−1 row-major)
  std::string why;                   // when not found: what failed
};

// Finds and refines the target's corners in a greyscale 8-bit image.
Detection detect_target(const TargetSpec& target, const cv::Mat& grey);

}  // namespace dentmark::calibrate
