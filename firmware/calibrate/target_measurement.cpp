#include "dentmark/firmware/calibrate/target_measurement.h"

#include <algorithm>
#include <cstdio>
#include <opencv2/calib3d.hpp>
#include <utility>

#include "dentmark/common/geometry/rigid_fit.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"

namespace dentmark::calibrate {
namespace {

// Pixels of each corner id, or empty when the board was not found whole.
std::vector<cv::Point2f> full_board(const TargetSpec& target, const Detection& d) {
  const int n = target.corner_count();
  if (!d.found || static_cast<int>(d.ids.size()) != n) return {};
  std::vector<cv::Point2f> by_id(static_cast<std::size_t>(n));
  std::vector<bool> seen(static_cast<std::size_t>(n), false);
  for (std::size_t k = 0; k < d.ids.size(); ++k) {
    const int id = d.ids[k];
    if (id < 0 || id >= n || seen[static_cast<std::size_t>(id)]) return {};
    seen[static_cast<std::size_t>(id)] = true;
    by_id[static_cast<std::size_t>(id)] = d.corners[k];
  }
  return by_id;
}

double grey_at(const cv::Mat& img, cv::Point2f p) {
  const cv::Rect r(cvRound(p.x) - 1, cvRound(p.y) - 1, 3, 3);
  if ((r & cv::Rect(0, 0, img.cols, img.rows)) != r) return -1.0;
  return cv::mean(img(r))[0];
}

// OpenCV returns a chessboard's corners in rows of COLS, but may start from any of the
// grid's four ends and run either way round. The target's convention fixes the order:
//   1. handedness: the printed face looks at the camera (its z axis towards it), so
//      with image y down the row step d_i and the column step d_j satisfy
//      d_i × d_j < 0; otherwise every row is reversed;
//   2. the half turn left: the square beyond corner 0 is black, the one beyond the
//      last corner white (COLS + ROWS odd, require_oriented_chessboard); otherwise the
//      whole order is reversed.
// False when the end squares cannot be read (outside the image).
bool orient_chessboard(const TargetSpec& t, const cv::Mat& img, std::vector<cv::Point2f>& by_id) {
  const std::size_t n = by_id.size(), c = static_cast<std::size_t>(t.cols);
  if (n < c + 2 || n % c != 0) return false;
  const cv::Point2f di = by_id[1] - by_id[0], dj = by_id[c] - by_id[0];
  if (di.x * dj.y - di.y * dj.x > 0.0f)
    for (std::size_t r = 0; r < n; r += c)
      std::reverse(by_id.begin() + static_cast<long>(r), by_id.begin() + static_cast<long>(r + c));
  const cv::Point2f first = by_id[0] - 0.5f * (by_id[1] - by_id[0]) - 0.5f * (by_id[c] - by_id[0]);
  const cv::Point2f last =
      by_id[n - 1] + 0.5f * (by_id[n - 1] - by_id[n - 2]) + 0.5f * (by_id[n - 1] - by_id[n - 1 - c]);
  const double a = grey_at(img, first), b = grey_at(img, last);
  if (a < 0.0 || b < 0.0) return false;
  if (a > b) std::reverse(by_id.begin(), by_id.end());
  return true;
}

}  // namespace

void require_oriented_chessboard(const TargetSpec& t) {
  if (t.kind == TargetKind::kChessboard && (t.cols + t.rows) % 2 == 0)
    throw CalibrateError("--target " + t.describe() +
                         ": a robot target's chessboard needs COLS + ROWS odd (e.g. 7x6): with both even or "
                         "both odd its two ends look alike and its orientation is ambiguous");
}

TargetMeasurement measure_target(const TargetSpec& target, const track::StereoCalibration& stereo,
                                 const cv::Mat& left, const cv::Mat& right, double max_reprojection_px) {
  TargetMeasurement m;
  if (left.size() != stereo.size || right.size() != stereo.size) {
    m.why = "image size differs from the stereo calibration's";
    return m;
  }
  // OpenCV's full chessboard search takes seconds to give up on an image without the
  // board (and longer on its 2x retry); its quick check (the one CALIB_CB_FAST_CHECK
  // runs) rules such images out first.
  if (target.kind == TargetKind::kChessboard)
    for (const auto& [img, side] : {std::pair{&left, "left"}, std::pair{&right, "right"}})
      if (!cv::checkChessboard(*img, cv::Size(target.cols, target.rows))) {
        m.why = std::string(side) + " camera: no chessboard in view";
        return m;
      }
  const Detection dl = detect_target(target, left), dr = detect_target(target, right);
  std::vector<cv::Point2f> pl = full_board(target, dl), pr = full_board(target, dr);
  if (pl.empty() || pr.empty()) {
    m.why = std::string(pl.empty() ? "left" : "right") + " camera: " +
            ((pl.empty() ? dl : dr).why.empty() ? "target not seen whole" : (pl.empty() ? dl : dr).why);
    return m;
  }
  if (target.kind == TargetKind::kChessboard &&
      (!orient_chessboard(target, left, pl) || !orient_chessboard(target, right, pr))) {
    m.why = "the board's end squares are outside an image: orientation unknown";
    return m;
  }
  const std::vector<cv::Point2d> nl = stereo.normalize(track::Cam::kLeft, pl);
  const std::vector<cv::Point2d> nr = stereo.normalize(track::Cam::kRight, pr);
  std::vector<Eigen::Vector3d> board;
  for (std::size_t j = 0; j < nl.size(); ++j) {
    const track::Triangulation t = track::triangulate(stereo, nl[j], nr[j]);
    m.points_camL.push_back(t.p_camL);
    m.max_reprojection_px = std::max(m.max_reprojection_px, t.reprojection_px);
    const cv::Point3f c = target.corner(static_cast<int>(j));
    board.emplace_back(c.x, c.y, c.z);
  }
  if (m.max_reprojection_px > max_reprojection_px) {
    char b[120];
    std::snprintf(b, sizeof b, "a corner triangulates %.2f px off (limit %.2f px)", m.max_reprojection_px,
                  max_reprojection_px);
    m.why = b;
    m.points_camL.clear();
    return m;
  }
  m.T_camL_target = fit_rigid(board, m.points_camL).T_to_from;
  m.pixels_left = std::move(pl);
  m.pixels_right = std::move(pr);
  m.found = true;
  return m;
}

}  // namespace dentmark::calibrate
