#pragma once
// The scanner target's spheres found in a scan (points in the scanner's frame 'sls'):
//   1. the plate: the plane with most points within 2 mm (RANSAC, 300 draws, then a
//      total-least-squares refit of its points, common/geometry/plane_fit.h), its normal
//      turned towards the sensor (the sls origin);
//   2. what stands off it: points 3 mm or more in front of the plate, grouped into
//      connected clusters on a grid of half-radius cells (cells of fewer than 3 points
//      left out: isolated outliers);
//   3. each cluster's sphere: a start by RANSAC (algebraic spheres, |p|² = 2 c·p + k,
//      through 4 random points, of the nominal radius within 10 %, scored by the points
//      within 1 mm of it), then the centre of a sphere of the known radius by
//      Gauss-Newton on the radial residuals |p − c| − r, three times keeping only the
//      points within max(3 robust σ, 0.3 mm) (not the stem, the plate's edge, outliers).
// A cluster is a sphere when ≥ 30 points remain, they spread across the line of sight
// by at least a quarter radius (1σ; a ball's face gives half a radius, a ring of a stem
// much less), their RMS residual is under 1 mm and the algebraic radius of the kept
// points is within 10 % of the nominal one. Two spheres closer than a radius are one
// (a ball split into two clusters): the one with more points is kept.

#include <Eigen/Core>
#include <span>
#include <string>
#include <vector>

namespace dentmark::calibrate {

struct ScanSphere {
  Eigen::Vector3d centre_sls = Eigen::Vector3d::Zero();
  double radius_free_m = 0.0;  // algebraic fit of the kept points (a check on the nominal radius)
  double rms_m = 0.0;          // RMS radial residual of the kept points at the nominal radius
  std::size_t points = 0;      // kept points
};

struct ScanSpheres {
  std::vector<ScanSphere> spheres;
  std::size_t plate_points = 0;
  double plate_rms_m = 0.0;
  std::vector<std::string> rejected;  // clusters that were not spheres, and why
};

// points: finite points in metres (NaN points are skipped). Throws CalibrateError when no
// plate is found (fewer than 1000 points in one plane).
ScanSpheres find_scan_spheres(std::span<const Eigen::Vector3d> points, double radius_m);

}  // namespace dentmark::calibrate
