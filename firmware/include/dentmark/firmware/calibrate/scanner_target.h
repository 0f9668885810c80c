#pragma once
// The scanner calibration's target (docs/calibration.md, "Scanner to stereo"): one rigid
// plate that both sensors resolve. The cameras see a printed chessboard on it (its
// corners triangulated give the board's pose, target_measurement.h); the structured-light
// scanner, blind to print, sees N ≥ 4 precision spheres (tooling balls on stems) fixed to
// the plate at known positions in the board's frame. Each sphere's centre is therefore
// known in camL (board pose · drawing) and measured in the scan: the common points of
// the rigid fit T_camL_sls.
//
// File (OpenCV FileStorage YAML, `--target`):
//   pattern: "chessboard:9x6"     COLS + ROWS odd (the board's orientation is read from it)
//   square: 0.060                 m, measured on the print
//   sphere_radius: 0.0190         m, the balls' nominal radius
//   spheres_board: N×3 matrix     m, ball centres in the board frame (corner 0 at the
//                                 origin, x along the rows, y along the columns, z out of
//                                 the printed face), from the plate's drawing or a CMM
// The layout must be asymmetric: every two spheres' distance differs from every other
// pair's by at least 20 mm, so the scan's unordered spheres match the drawing's uniquely.

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "dentmark/firmware/calibrate/calibration_target.h"

namespace dentmark::calibrate {

struct ScannerTarget {
  TargetSpec board;
  double sphere_radius_m = 0.0;
  std::vector<Eigen::Vector3d> spheres_board;
};

// Throws CalibrateError naming the file and the field: a missing field, a pattern that is
// not an oriented chessboard, a radius outside 5–100 mm, fewer than 4 or more than 8
// spheres, two spheres overlapping, or a layout whose pairwise distances are not all
// distinct by 20 mm.
ScannerTarget read_scanner_target(const std::filesystem::path& path);
void write_scanner_target(const std::filesystem::path& path, const ScannerTarget& target);
// The checks of read_scanner_target on a target built in code; 'where' names it.
void check_scanner_target(const ScannerTarget& target, const std::string& where);

}  // namespace dentmark::calibrate
