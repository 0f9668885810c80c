#include "dentmark/firmware/calibrate/scanner_fit.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>

#include "dentmark/common/geometry/rigid_fit.h"
#include "dentmark/common/geometry/transform.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"

namespace dentmark::calibrate {
namespace {

constexpr double kMaxMatchRms = 0.002;  // m
constexpr double kMinMatchGap = 0.010;  // m: the next best assignment at least this much worse

std::string mm(double m) {
  char b[32];
  std::snprintf(b, sizeof b, "%.2f mm", m * 1e3);
  return b;
}

}  // namespace

SphereMatch match_spheres(const ScannerTarget& target, const std::vector<ScanSphere>& found,
                          const std::string& where) {
  const std::size_t n = target.spheres_board.size(), k = found.size();
  if (k < 3)
    throw CalibrateError(
        where + ": " + std::to_string(k) + " of the target's " + std::to_string(n) +
        " spheres found in the scan; at least 3 are needed (are they in the scanner's view?)");
  if (k > n) {
    std::string at;
    for (const ScanSphere& s : found) {
      char b[64];
      std::snprintf(b, sizeof b, " (%.3f, %.3f, %.3f)", s.centre_sls.x(), s.centre_sls.y(), s.centre_sls.z());
      at += b;
    }
    throw CalibrateError(where + ": " + std::to_string(k) + " spheres found in the scan, the target has " +
                         std::to_string(n) + ": something else of the same radius is in the scan; found at" +
                         at + " m");
  }
  std::vector<Eigen::Vector3d> to;
  for (const ScanSphere& s : found) to.push_back(s.centre_sls);
  // Every injective map found -> drawn: the first k of each permutation of the drawing's ids.
  std::vector<int> perm(n);
  std::iota(perm.begin(), perm.end(), 0);
  SphereMatch best;
  best.rms_m = best.next_rms_m = std::numeric_limits<double>::infinity();
  do {
    // Each injective map once: the permutations whose unused tail is in ascending order.
    if (!std::is_sorted(perm.begin() + static_cast<long>(k), perm.end())) continue;
    std::vector<int> ids(perm.begin(), perm.begin() + static_cast<long>(k));
    std::vector<Eigen::Vector3d> from;
    for (int id : ids) from.push_back(target.spheres_board[static_cast<std::size_t>(id)]);
    RigidFit f;
    try {
      f = fit_rigid(from, to);
    } catch (const GeometryError&) {
      continue;  // collinear spheres: no orientation
    }
    if (f.rms < best.rms_m) {
      best.next_rms_m = best.rms_m;
      best.rms_m = f.rms;
      best.ids = ids;
      best.T_sls_board = f.T_to_from;
    } else if (f.rms < best.next_rms_m) {
      best.next_rms_m = f.rms;
    }
  } while (std::next_permutation(perm.begin(), perm.end()));
  if (!(best.rms_m <= kMaxMatchRms))
    throw CalibrateError(where + ": the scan's " + std::to_string(k) +
                         " spheres do not match the target's drawing (best fit " + mm(best.rms_m) +
                         " RMS, limit " + mm(kMaxMatchRms) +
                         "): wrong --target file, or a sphere moved on the plate");
  if (best.next_rms_m - best.rms_m < kMinMatchGap)
    throw CalibrateError(where + ": the scan's " + std::to_string(k) +
                         " spheres match the drawing in two ways (" + mm(best.rms_m) + " and " +
                         mm(best.next_rms_m) + " RMS): too few spheres seen to tell them apart");
  return best;
}

ScannerFit fit_scanner(const std::vector<ScannerCapture>& captures, const TargetSpec& board,
                       const track::StereoCalibration& stereo) {
  std::vector<Eigen::Vector3d> sls, camL;
  for (const ScannerCapture& c : captures) {
    sls.insert(sls.end(), c.points_sls.begin(), c.points_sls.end());
    camL.insert(camL.end(), c.points_camL.begin(), c.points_camL.end());
  }
  if (sls.size() < 4)
    throw CalibrateError("scanner calibration: " + std::to_string(sls.size()) +
                         " common points over all captures; at least 4 are needed");
  ScannerFit out;
  out.captures = static_cast<int>(captures.size());
  out.points = static_cast<int>(sls.size());
  try {
    out.T_camL_sls_points = fit_rigid(sls, camL).T_to_from;
  } catch (const GeometryError& e) {
    throw CalibrateError(
        std::string("scanner calibration: the common points do not fix a rigid transform (") + e.what() +
        ")");
  }
  out.T_camL_sls = out.T_camL_sls_points;
  std::vector<BoardView> views;
  for (const ScannerCapture& c : captures)
    if (!c.board_view.pixels_left.empty()) views.push_back(c.board_view);
  if (views.size() == captures.size()) {
    const ChainedPose refined = refine_chained_pose(board, stereo, views, out.T_camL_sls_points);
    out.T_camL_sls = refined.T_camL_x;
    out.corners_rms_px = refined.rms_px;
  }
  double ss = 0.0;
  for (std::size_t i = 0; i < sls.size(); ++i) {
    const double e = (out.T_camL_sls * sls[i] - camL[i]).norm();
    ss += e * e, out.max_m = std::max(out.max_m, e);
  }
  out.rms_m = std::sqrt(ss / static_cast<double>(sls.size()));
  if (sls.size() >= 5) {
    double hs = 0.0;
    out.holdout_max_m = 0.0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < sls.size(); ++i) {
      std::vector<Eigen::Vector3d> a, b;
      for (std::size_t j = 0; j < sls.size(); ++j)
        if (j != i) a.push_back(sls[j]), b.push_back(camL[j]);
      try {
        const Transform t = fit_rigid(a, b).T_to_from;
        const double e = (t * sls[i] - camL[i]).norm();
        hs += e * e, out.holdout_max_m = std::max(out.holdout_max_m, e), ++n;
      } catch (const GeometryError&) {
      }
    }
    if (n > 0) out.holdout_rms_m = std::sqrt(hs / static_cast<double>(n));
  }
  return out;
}

}  // namespace dentmark::calibrate
