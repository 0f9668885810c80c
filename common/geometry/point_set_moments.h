#pragma once
// Weighted centroid and scatter of a 3D point set, with the input checks shared by
// the rigid and plane fits. Private to common/geometry.

#include <Eigen/Core>
#include <span>
#include <string>

namespace dentmark::detail {

struct PointSetMoments {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();  // Σ w (p − c)(p − c)ᵀ
  double weight_sum = 0.0;
  std::size_t weighted_count = 0;  // points with w > 0
};

// Validates sizes, finiteness and weights (throws GeometryError prefixed by 'who').
PointSetMoments point_set_moments(std::span<const Eigen::Vector3d> points, std::span<const double> weights,
                                  const std::string& who);

// True when the scatter's second largest eigenvalue is negligible against the largest:
// the points lie on a line (or a single point).
bool is_collinear(const Eigen::Matrix3d& scatter);

}  // namespace dentmark::detail
