// dentmark's ChArUco module (charuco_module.h): the ChArUco target's dictionaries and
// detection through OpenCV's aruco, loaded by the calibration commands on first use.
#include "dentmark/firmware/calibrate/charuco_module.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <opencv2/aruco/charuco.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <utility>

namespace dentmark::calibrate {
namespace {

// OpenCV 4.6's cv::aruco::PREDEFINED_DICTIONARY_NAME, by name.
constexpr std::array<std::pair<const char*, int>, 21> kDictionaries{{
    {"DICT_4X4_50", cv::aruco::DICT_4X4_50},
    {"DICT_4X4_100", cv::aruco::DICT_4X4_100},
    {"DICT_4X4_250", cv::aruco::DICT_4X4_250},
    {"DICT_4X4_1000", cv::aruco::DICT_4X4_1000},
    {"DICT_5X5_50", cv::aruco::DICT_5X5_50},
    {"DICT_5X5_100", cv::aruco::DICT_5X5_100},
    {"DICT_5X5_250", cv::aruco::DICT_5X5_250},
    {"DICT_5X5_1000", cv::aruco::DICT_5X5_1000},
    {"DICT_6X6_50", cv::aruco::DICT_6X6_50},
    {"DICT_6X6_100", cv::aruco::DICT_6X6_100},
    {"DICT_6X6_250", cv::aruco::DICT_6X6_250},
    {"DICT_6X6_1000", cv::aruco::DICT_6X6_1000},
    {"DICT_7X7_50", cv::aruco::DICT_7X7_50},
    {"DICT_7X7_100", cv::aruco::DICT_7X7_100},
    {"DICT_7X7_250", cv::aruco::DICT_7X7_250},
    {"DICT_7X7_1000", cv::aruco::DICT_7X7_1000},
    {"DICT_ARUCO_ORIGINAL", cv::aruco::DICT_ARUCO_ORIGINAL},
    {"DICT_APRILTAG_16h5", cv::aruco::DICT_APRILTAG_16h5},
    {"DICT_APRILTAG_25h9", cv::aruco::DICT_APRILTAG_25h9},
    {"DICT_APRILTAG_36h10", cv::aruco::DICT_APRILTAG_36h10},
    {"DICT_APRILTAG_36h11", cv::aruco::DICT_APRILTAG_36h11},
}};

int dictionary_id(const char* name) {
  for (const auto& [n, id] : kDictionaries)
    if (std::strcmp(n, name) == 0) return id;
  return -1;
}

int dictionary_size(int id) {
  return cv::aruco::getPredefinedDictionary(id)->bytesList.rows;
}

Detection detect_charuco(const TargetSpec& t, const cv::Mat& grey) {
  Detection out;
  const cv::Ptr<cv::aruco::Dictionary> dict = cv::aruco::getPredefinedDictionary(t.dictionary_id);
  const cv::Ptr<cv::aruco::CharucoBoard> board = cv::aruco::CharucoBoard::create(
      t.cols, t.rows, static_cast<float>(t.square_m), static_cast<float>(t.marker_m), dict);
  std::vector<std::vector<cv::Point2f>> marker_corners;
  std::vector<int> marker_ids;
  const cv::Ptr<cv::aruco::DetectorParameters> params = cv::aruco::DetectorParameters::create();
  params->cornerRefinementMethod = cv::aruco::CORNER_REFINE_NONE;  // the chessboard corners are refined below
  cv::aruco::detectMarkers(grey, dict, marker_corners, marker_ids, params);
  if (marker_ids.empty()) {
    out.why = "no " + t.dictionary + " markers found";
    return out;
  }
  cv::aruco::interpolateCornersCharuco(marker_corners, marker_ids, grey, board, out.corners, out.ids);
  if (out.corners.size() < 6) {
    out.why = std::to_string(out.corners.size()) + " ChArUco corners found (need 6)";
    out.corners.clear();
    out.ids.clear();
    return out;
  }
  // Window half-size: inside the white gap between the corner and the nearest marker
  // ((square − marker) / 2), whose edges would pull the saddle point. Pixels per metre
  // from the detected markers' mean side.
  double side_px = 0.0;
  for (const auto& q : marker_corners)
    for (int k = 0; k < 4; ++k)
      side_px += cv::norm(q[static_cast<std::size_t>(k)] - q[static_cast<std::size_t>((k + 1) % 4)]);
  side_px /= 4.0 * static_cast<double>(marker_corners.size());
  const double gap_px = 0.5 * (t.square_m - t.marker_m) * side_px / t.marker_m;
  const int half = std::clamp(static_cast<int>(gap_px) - 1, 2, 11);
  cv::cornerSubPix(grey, out.corners, cv::Size(half, half), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-4));
  out.found = true;
  return out;
}

}  // namespace
}  // namespace dentmark::calibrate

extern "C" __attribute__((visibility("default"))) const dentmark::calibrate::CharucoModule*
dentmark_charuco_module() {
  using namespace dentmark::calibrate;
  static const CharucoModule module{kCharucoModuleAbi, &dictionary_id, &dictionary_size, &detect_charuco};
  return &module;
}
