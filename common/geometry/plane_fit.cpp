#include "dentmark/common/geometry/plane_fit.h"

#include <Eigen/Eigenvalues>
#include <cmath>

#include "point_set_moments.h"

namespace dentmark {

Plane fit_plane(std::span<const Eigen::Vector3d> points, std::span<const double> weights,
                const Eigen::Vector3d& normal_hint) {
  const detail::PointSetMoments m = detail::point_set_moments(points, weights, "fit_plane");
  if (detail::is_collinear(m.scatter)) throw GeometryError("fit_plane: points are collinear");
  // The normal is the scatter's eigenvector of least eigenvalue; that eigenvalue is
  // the weighted sum of squared orthogonal distances.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(m.scatter);
  Plane plane;
  plane.centroid = m.centroid;
  plane.normal = eig.eigenvectors().col(0).normalized();
  if (normal_hint.allFinite() && plane.normal.dot(normal_hint) < 0.0) plane.normal = -plane.normal;
  plane.rms = std::sqrt(std::max(0.0, eig.eigenvalues()(0)) / m.weight_sum);
  return plane;
}

}  // namespace dentmark
