#include "dentmark/firmware/calibrate/calibration_poses.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "dentmark/firmware/calibrate/calibrate_error.h"

namespace dentmark::calibrate {
namespace {

// Radical inverse of i in a prime base: the Halton sequence's coordinate in [0, 1).
double halton(int i, int base) {
  double f = 1.0, r = 0.0;
  for (int k = i; k > 0; k /= base) {
    f /= base;
    r += f * (k % base);
  }
  return r;
}

// The board's outline including its one-square border (calibration_target.h's frame).
std::vector<Eigen::Vector3d> outline(const TargetSpec& t) {
  const double s = t.square_m;
  // Chessboard: inner corners span [0, (cols−1)s]; ChArUco: squares span [0, cols·s].
  const double w = t.kind == TargetKind::kChessboard ? (t.cols - 1) * s : t.cols * s;
  const double h = t.kind == TargetKind::kChessboard ? (t.rows - 1) * s : t.rows * s;
  const double b = t.kind == TargetKind::kChessboard ? 2.0 * s : 0.5 * s;
  return {{-b, -b, 0.0}, {w + b, -b, 0.0}, {w + b, h + b, 0.0}, {-b, h + b, 0.0}};
}

}  // namespace

bool target_visible(const track::StereoCalibration& stereo, const TargetSpec& target,
                    const Transform& T_camL_target, const PosePlanOptions& o, std::string* why) {
  auto fail = [&](const std::string& w) {
    if (why) *why = w;
    return false;
  };
  const Eigen::Vector3d normal = T_camL_target.linear().col(2);
  const Eigen::Vector3d centre = T_camL_target * Eigen::Vector3d(0.5 * target.cols * target.square_m,
                                                                 0.5 * target.rows * target.square_m, 0.0);
  const Transform T_camL_camR = stereo.T_camR_camL.inverse();
  const double cos_max = std::cos(o.max_view_angle);
  const Eigen::Vector3d eyes[2] = {Eigen::Vector3d::Zero(), T_camL_camR.translation()};
  for (const Eigen::Vector3d& eye : eyes) {
    const Eigen::Vector3d to_eye = (eye - centre).normalized();
    if (normal.dot(to_eye) < cos_max) return fail("the board does not face the cameras");
  }
  std::vector<Eigen::Vector3d> corners;
  for (const Eigen::Vector3d& p : outline(target)) corners.push_back(T_camL_target * p);
  for (const Eigen::Vector3d& p : corners) {
    if (p.z() < 0.2 || (stereo.T_camR_camL * p).z() < 0.2) return fail("the board is behind a camera");
  }
  for (track::Cam c : {track::Cam::kLeft, track::Cam::kRight}) {
    for (const cv::Point2f& px : stereo.project(c, corners))
      if (px.x < o.image_margin_px || px.y < o.image_margin_px ||
          px.x > stereo.size.width - 1 - o.image_margin_px ||
          px.y > stereo.size.height - 1 - o.image_margin_px)
        return fail(std::string("the board leaves the ") + (c == track::Cam::kLeft ? "left" : "right") +
                    " image");
  }
  return true;
}

std::vector<Transform> plan_calibration_poses(const ToolTarget& target,
                                              const track::StereoCalibration& stereo,
                                              const Transform& T_base_camL_prior,
                                              const Transform& T_base_tool_start, const PosePlanOptions& o) {
  const Eigen::Vector3d lo = o.workspace_min.array() + o.workspace_margin;
  const Eigen::Vector3d hi = o.workspace_max.array() - o.workspace_margin;
  if ((hi.array() <= lo.array()).any())
    throw CalibrateError("limits.workspace: smaller than twice the planner's margin");
  const Transform T_camL_base = T_base_camL_prior.inverse();
  std::vector<Transform> kept;
  std::map<std::string, int> rejected;  // why candidates failed, for the error message
  for (int i = o.halton_offset;
       i < o.halton_offset + o.max_candidates && static_cast<int>(kept.size()) < o.poses; ++i) {
    const Eigen::Vector3d u(halton(i, 2), halton(i, 3), halton(i, 5));
    const Eigen::Vector3d p = lo.array() + u.array() * (hi - lo).array();
    const Eigen::Vector3d tilt =
        o.max_tilt * Eigen::Vector3d(2 * halton(i, 7) - 1, 2 * halton(i, 11) - 1, 2 * halton(i, 13) - 1);
    Transform T_base_tool = Transform::Identity();
    T_base_tool.linear() =
        T_base_tool_start.linear() * make_transform_rotvec(tilt, Eigen::Vector3d::Zero()).linear();
    T_base_tool.translation() = p;
    std::string why;
    if (!target_visible(stereo, target.spec, T_camL_base * T_base_tool * target.T_tool_target, o, &why)) {
      ++rejected[why];
      continue;
    }
    const bool crowded = std::any_of(kept.begin(), kept.end(), [&](const Transform& k) {
      return (k.translation() - p).norm() < o.min_separation;
    });
    if (!crowded) kept.push_back(T_base_tool);
  }
  if (static_cast<int>(kept.size()) < o.poses) {
    std::string reasons;
    for (const auto& [why, count] : rejected)
      reasons += (reasons.empty() ? "" : ", ") + why + " (" + std::to_string(count) + ")";
    throw CalibrateError("only " + std::to_string(kept.size()) + " of " + std::to_string(o.poses) +
                         " poses inside limits.workspace show the whole target to both cameras (candidates "
                         "rejected: " +
                         reasons + "): check the board's limits, the target's size and the start pose");
  }
  // Greedy nearest neighbour from the start: short moves.
  std::vector<Transform> ordered;
  Eigen::Vector3d at = T_base_tool_start.translation();
  while (!kept.empty()) {
    auto next = std::min_element(kept.begin(), kept.end(), [&](const Transform& a, const Transform& b) {
      return (a.translation() - at).norm() < (b.translation() - at).norm();
    });
    at = next->translation();
    ordered.push_back(*next);
    kept.erase(next);
  }
  return ordered;
}

}  // namespace dentmark::calibrate
