#pragma once
// Scanner-to-stereo, T_camL_sls, from captures of the scanner target (scanner_target.h):
// in each capture the spheres found in the scan (scan_spheres.h) are matched to the
// drawing's, and the board's pose measured by the stereo pair (target_measurement.h)
// puts the same sphere centres into camL. T_camL_sls is the least-squares rigid fit of
// all captures' sls centres onto their camL centres (Arun/Horn,
// common/geometry/rigid_fit.h).
//
// Matching: every assignment of the found spheres to distinct drawn ones is tried
// (at most 8!/(8−k)! for k found); each is scored by the RMS of the rigid fit of the
// drawing onto the found centres. The best must fit within 2 mm and the next best be
// at least 10 mm worse, or the match is refused (a wrong or symmetric drawing).

#include <Eigen/Core>
#include <string>
#include <vector>

#include "dentmark/common/geometry/transform.h"
#include "dentmark/firmware/calibrate/scan_spheres.h"
#include "dentmark/firmware/calibrate/scanner_target.h"

namespace dentmark::calibrate {

// One capture's common points: sphere i of the drawing (ids) at points_sls[k] in the
// scan and at points_camL[k] through the board's measured pose.
struct ScannerCapture {
  std::string name;
  std::vector<int> ids;
  std::vector<Eigen::Vector3d> points_sls, points_camL;
  double match_rms_m = 0.0;   // the drawing fitted onto the scan's centres (the plate as built vs drawn)
  double board_rms_px = 0.0;  // the board's corners' reprojection error at its measured pose (both cameras)
  std::vector<std::string> not_spheres;  // clusters in front of the plate that were not taken, and why
};

struct SphereMatch {
  std::vector<int> ids;  // drawing id of each found sphere
  double rms_m = 0.0, next_rms_m = 0.0;
  Transform T_sls_board = Transform::Identity();
};

// Throws CalibrateError naming 'where' when fewer than 3 spheres were found, more than
// the drawing has, or the match is not clear (see above).
SphereMatch match_spheres(const ScannerTarget& target, const std::vector<ScanSphere>& found,
                          const std::string& where);

struct ScannerFit {
  Transform T_camL_sls = Transform::Identity();
  double rms_m = 0.0;         // RMS point transfer of all common points with the fit
  double max_m = 0.0;         // worst point
  double holdout_rms_m = -1;  // each point left out of the fit in turn and transferred (≥ 5 points)
  double holdout_max_m = -1;  // worst left-out point
  int captures = 0, points = 0;
};

// Needs ≥ 4 common points over all captures, not all collinear. Throws CalibrateError.
ScannerFit fit_scanner(const std::vector<ScannerCapture>& captures);

}  // namespace dentmark::calibrate
