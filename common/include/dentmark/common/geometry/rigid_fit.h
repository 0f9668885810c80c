#pragma once
// Weighted least-squares rigid motion between two corresponding 3D point sets:
// K. S. Arun, T. S. Huang, S. D. Blostein, "Least-squares fitting of two 3-D point
// sets", IEEE PAMI 9(5), 1987, with the reflection correction of S. Umeyama,
// IEEE PAMI 13(4), 1991.

#include <Eigen/Core>
#include <cstddef>
#include <span>

#include "dentmark/common/geometry/transform.h"

namespace dentmark {

struct RigidFit {
  // Maps 'from' coordinates onto 'to' coordinates: to_i ≈ T_to_from * from_i.
  Transform T_to_from = Transform::Identity();
  // Weighted RMS of the residuals |to_i − T·from_i| in metres.
  double rms = 0.0;
  std::size_t count = 0;
};

// Minimises Σ w_i |to_i − (R from_i + t)|² over rotations R (det +1) and t.
// weights may be empty (all 1). Throws GeometryError when the sizes differ, fewer
// than 3 points carry positive weight, a value is non-finite, a weight is negative,
// or the points are collinear (rotation about the line undetermined).
RigidFit fit_rigid(std::span<const Eigen::Vector3d> from, std::span<const Eigen::Vector3d> to,
                   std::span<const double> weights = {});

}  // namespace dentmark
