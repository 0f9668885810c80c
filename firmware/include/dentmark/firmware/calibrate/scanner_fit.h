#pragma once
// Scanner-to-stereo, T_camL_sls, from captures of the scanner target (scanner_target.h):
// in each capture the spheres found in the scan (scan_spheres.h) are matched to the
// drawing's, and the board's pose measured by the stereo pair (target_measurement.h)
// puts the same sphere centres into camL. The least-squares rigid fit of all captures'
// sls centres onto their camL centres (Arun/Horn, common/geometry/rigid_fit.h) starts
// T_camL_sls; it is then refined on the board's corners (board_pose.h,
// refine_chained_pose): each capture's board placed in sls by its scanned spheres
// (T_sls_board, the drawing fitted onto the scan's centres) and projected into both
// images through T_camL_sls, every corner of every capture in one least-squares
// problem over T_camL_sls's 6 parameters.
//
// Why the refinement: the scan fixes the board's pose to a few hundredths of a
// millimetre, the cameras at 2.8 m only to a few tenths, and far worse along the
// viewing rays and in the board's tilt than across them. The point fit gives every
// sphere centre the same isotropic weight, so it averages the captures' board poses
// without regard to which of their directions the images fixed well; the reprojection
// error weighs each direction of each capture by what the images resolve, the
// maximum-likelihood estimate when the corners' pixel noise is the error that counts.
//
// Matching: every assignment of the found spheres to distinct drawn ones is tried
// (at most 8!/(8−k)! for k found); each is scored by the RMS of the rigid fit of the
// drawing onto the found centres. The best must fit within 2 mm and the next best be
// at least 10 mm worse, or the match is refused (a wrong or symmetric drawing).

#include <Eigen/Core>
#include <string>
#include <vector>

#include "dentmark/common/geometry/transform.h"
#include "dentmark/firmware/calibrate/board_pose.h"
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
  // The board's corners in both images, with T_x_target the board's pose in sls from the
  // scanned spheres (SphereMatch::T_sls_board): what the refinement fits on.
  BoardView board_view;
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
  double rms_m = 0.0;          // RMS point transfer of all common points with the fit
  double max_m = 0.0;          // worst point
  double holdout_rms_m = -1;   // each point left out of the fit in turn and transferred (≥ 5 points)
  double holdout_max_m = -1;   // worst left-out point
  double corners_rms_px = -1;  // every capture's corners reprojected through T_camL_sls · T_sls_board
  Transform T_camL_sls_points = Transform::Identity();  // the point fit the refinement started from
  int captures = 0, points = 0;
};

// Needs ≥ 4 common points over all captures, not all collinear. Throws CalibrateError.
// The refinement needs each capture's board_view (its corners in both images); without
// them T_camL_sls is the point fit. rms_m and max_m are the point transfer with the
// result; the hold-out is the point fit's (each point left out of it in turn).
ScannerFit fit_scanner(const std::vector<ScannerCapture>& captures, const TargetSpec& board,
                       const track::StereoCalibration& stereo);

}  // namespace dentmark::calibrate
