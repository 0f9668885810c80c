#include "point_set_moments.h"

#include <Eigen/Eigenvalues>
#include <cmath>

#include "dentmark/common/geometry/transform.h"

namespace dentmark::detail {

PointSetMoments point_set_moments(std::span<const Eigen::Vector3d> points, std::span<const double> weights,
                                  const std::string& who) {
  if (!weights.empty() && weights.size() != points.size())
    throw GeometryError(who + ": " + std::to_string(weights.size()) + " weights for " +
                        std::to_string(points.size()) + " points");
  PointSetMoments m;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double w = weights.empty() ? 1.0 : weights[i];
    if (!std::isfinite(w) || w < 0.0)
      throw GeometryError(who + ": weight " + std::to_string(i) + " is negative or not finite");
    if (!points[i].allFinite()) throw GeometryError(who + ": point " + std::to_string(i) + " is not finite");
    if (w == 0.0) continue;
    sum += w * points[i];
    m.weight_sum += w;
    ++m.weighted_count;
  }
  if (m.weighted_count < 3)
    throw GeometryError(who + ": needs at least 3 points with positive weight, got " +
                        std::to_string(m.weighted_count));
  m.centroid = sum / m.weight_sum;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double w = weights.empty() ? 1.0 : weights[i];
    const Eigen::Vector3d d = points[i] - m.centroid;
    m.scatter += w * d * d.transpose();
  }
  return m;
}

bool is_collinear(const Eigen::Matrix3d& scatter) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter, Eigen::EigenvaluesOnly);
  const Eigen::Vector3d ev = eig.eigenvalues();  // ascending
  // Relative tolerance: double precision leaves ~1e-16 relative noise in the scatter.
  return !(ev(2) > 0.0) || ev(1) <= 1e-12 * ev(2);
}

}  // namespace dentmark::detail
