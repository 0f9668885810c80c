#include "dentmark/firmware/calibrate/calibration_target.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <regex>
#include <utility>

#include "dentmark/firmware/calibrate/calibrate_error.h"
#include "dentmark/firmware/calibrate/charuco_module.h"

namespace dentmark::calibrate {
namespace {

std::string format_m(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

// Smallest distance between neighbouring corners, pixels: bounds the refinement window.
double min_neighbour_distance(const std::vector<cv::Point2f>& c, int cols) {
  double d = 1e9;
  for (std::size_t i = 0; i < c.size(); ++i) {
    if ((static_cast<int>(i) + 1) % cols != 0 && i + 1 < c.size()) d = std::min(d, cv::norm(c[i + 1] - c[i]));
    if (i + static_cast<std::size_t>(cols) < c.size())
      d = std::min(d, cv::norm(c[i + static_cast<std::size_t>(cols)] - c[i]));
  }
  return d;
}

Detection detect_chessboard(const TargetSpec& t, const cv::Mat& grey) {
  Detection out;
  const cv::Size pattern(t.cols, t.rows);
  const int flags = cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE;
  bool found = cv::findChessboardCorners(grey, pattern, out.corners, flags);
  if (!found) {
    // Small or distant boards: the detector's quad search works better on an
    // upsampled image (as OpenCV's stereo_calib sample does).
    cv::Mat big;
    cv::resize(grey, big, cv::Size(), 2.0, 2.0, cv::INTER_LINEAR_EXACT);
    found = cv::findChessboardCorners(big, pattern, out.corners, flags);
    for (auto& p : out.corners) p *= 0.5f;
  }
  if (!found) {
    out.corners.clear();
    out.why = "no " + std::to_string(t.cols) + "x" + std::to_string(t.rows) + " chessboard found";
    return out;
  }
  // Window half-size: OpenCV's sample uses 11 px; never reach the neighbouring corner,
  // whose edges would pull the saddle point.
  const int half = std::clamp(static_cast<int>(0.5 * min_neighbour_distance(out.corners, t.cols)) - 1, 3, 11);
  cv::cornerSubPix(grey, out.corners, cv::Size(half, half), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-4));
  out.ids.resize(out.corners.size());
  for (std::size_t i = 0; i < out.ids.size(); ++i) out.ids[i] = static_cast<int>(i);
  out.found = true;
  return out;
}

}  // namespace

int TargetSpec::corner_count() const {
  return kind == TargetKind::kChessboard ? cols * rows : (cols - 1) * (rows - 1);
}

cv::Point3f TargetSpec::corner(int id) const {
  const int across = kind == TargetKind::kChessboard ? cols : cols - 1;
  const int offset = kind == TargetKind::kChessboard ? 0 : 1;  // ChArUco's corners start one square in
  const double s = square_m;
  return {static_cast<float>((id % across + offset) * s), static_cast<float>((id / across + offset) * s),
          0.0f};
}

std::string TargetSpec::describe() const {
  if (kind == TargetKind::kChessboard)
    return "chessboard:" + std::to_string(cols) + "x" + std::to_string(rows) + " square " +
           format_m(square_m) + " m";
  return "charuco:" + std::to_string(cols) + "x" + std::to_string(rows) + " square " + format_m(square_m) +
         " m marker " + format_m(marker_m) + " m " + dictionary;
}

TargetSpec parse_target(const std::string& pattern, double square_m, double marker_m,
                        const std::string& dictionary) {
  static const std::regex re(R"(^(chessboard|charuco):([0-9]{1,3})x([0-9]{1,3})$)");
  std::smatch m;
  if (!std::regex_match(pattern, m, re))
    throw CalibrateError("--pattern: '" + pattern + "' is not chessboard:COLSxROWS or charuco:COLSxROWS");
  TargetSpec t;
  t.kind = m[1] == "chessboard" ? TargetKind::kChessboard : TargetKind::kCharuco;
  t.cols = std::stoi(m[2]);
  t.rows = std::stoi(m[3]);
  if (!(square_m > 0.0 && square_m < 1.0))
    throw CalibrateError("--square: " + format_m(square_m) + " m is not a square size (0 < s < 1 m)");
  t.square_m = square_m;
  if (t.kind == TargetKind::kChessboard) {
    if (t.cols < 3 || t.rows < 3)
      throw CalibrateError("--pattern: a chessboard needs at least 3x3 inner corners");
    if (t.cols == t.rows)
      throw CalibrateError("--pattern: a square chessboard (" + pattern +
                           ") has no defined orientation; use one with different counts, e.g. 9x6");
    if (!dictionary.empty() || marker_m != 0.0)
      throw CalibrateError("--marker and --dictionary apply to charuco patterns only");
    return t;
  }
  if (t.cols < 3 || t.rows < 3) throw CalibrateError("--pattern: a ChArUco board needs at least 3x3 squares");
  if (!(marker_m > 0.0 && marker_m < square_m))
    throw CalibrateError("--marker: " + format_m(marker_m) + " m must be positive and smaller than --square");
  t.marker_m = marker_m;
  const CharucoModule& charuco = charuco_module();
  t.dictionary_id = charuco.dictionary_id(dictionary.c_str());
  if (t.dictionary_id < 0)
    throw CalibrateError("--dictionary: '" + dictionary +
                         "' is not an OpenCV predefined dictionary (e.g. DICT_5X5_100)");
  t.dictionary = dictionary;
  const int markers = (t.cols * t.rows) / 2;
  const int available = charuco.dictionary_size(t.dictionary_id);
  if (markers > available)
    throw CalibrateError("--dictionary: " + dictionary + " has " + std::to_string(available) +
                         " markers; a " + std::to_string(t.cols) + "x" + std::to_string(t.rows) +
                         " board needs " + std::to_string(markers));
  return t;
}

Detection detect_target(const TargetSpec& t, const cv::Mat& grey) {
  CV_Assert(grey.type() == CV_8UC1);
  return t.kind == TargetKind::kChessboard ? detect_chessboard(t, grey) : charuco_module().detect(t, grey);
}

}  // namespace dentmark::calibrate
