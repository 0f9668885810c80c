#pragma once
// The twin's structured-light scan of the scanner calibration target (docs/calibration.md,
// "Scanner to stereo"): a flat plate carrying the printed chessboard and precision
// spheres on cylindrical stems. The scanner is modelled as in sim/scan (sls_scan.h): a
// perspective grid of rays from the sensor origin, each returning the nearest surface
// (plate, sphere or stem), with Gaussian range noise along the ray, a fraction of
// outliers thrown along the ray, and no return where nothing is hit.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "dentmark/common/geometry/transform.h"
#include "dentmark/sim/calibration/chessboard_renderer.h"

namespace dentmark::sim::calibration {

// Board frame: corner 0 at the origin, z out of the printed face (ChessboardTarget).
struct SphereTarget {
  ChessboardTarget board{9, 6, 0.06};
  double sphere_radius = 0.01905;                    // m (1.5 in tooling balls)
  double stem_radius = 0.006;                        // m
  std::vector<Eigen::Vector3d> spheres_board;        // centres, m; stems run from z = 0 to each
  Eigen::Vector2d plate_min{0, 0}, plate_max{0, 0};  // plate outline in the board plane, m
};

// The station twin's target: 9×6 chessboard of 60 mm squares (print 0.72 × 0.54 m with
// its border), five 38.1 mm balls at 45–70 mm stand-off outside the print, in a layout
// whose ten pairwise distances differ by at least 56 mm; plate 1.0 × 0.73 m.
SphereTarget twin_sphere_target();

struct SlsImaging {
  double spacing = 0.001;         // m between neighbouring rays at the target's distance
  double range_noise = 50e-6;     // m, 1σ along the ray
  double outlier_fraction = 0.0;  // points thrown 2–20 mm along their ray
  std::uint64_t seed = 1;
};

// Points in the sensor frame 'sls' (metres) of the target at T_sls_board.
std::vector<Eigen::Vector3f> scan_sphere_target(const SphereTarget& target, const Transform& T_sls_board,
                                                const SlsImaging& imaging);

}  // namespace dentmark::sim::calibration
