#pragma once
// Weighted least-squares plane (total least squares: minimises the sum of squared
// orthogonal distances). Used for the defect frame O_v (paper §IV-C, Fig. 6b).

#include <Eigen/Core>
#include <span>

#include "dentmark/common/geometry/transform.h"

namespace dentmark {

struct Plane {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  // weighted mean of the points, metres
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();   // unit normal
  double rms = 0.0;                                    // weighted RMS orthogonal distance, metres

  // Signed orthogonal distance of p from the plane along the normal, metres.
  double signed_distance(const Eigen::Vector3d& p) const { return normal.dot(p - centroid); }
};

// Fits a plane to the points. weights may be empty (all 1). If normal_hint is
// non-zero the normal is oriented so that normal·normal_hint >= 0. Throws
// GeometryError on fewer than 3 weighted points, non-finite values, negative
// weights, mismatched sizes, or collinear points.
Plane fit_plane(std::span<const Eigen::Vector3d> points, std::span<const double> weights = {},
                const Eigen::Vector3d& normal_hint = Eigen::Vector3d::Zero());

}  // namespace dentmark
