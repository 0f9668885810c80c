#include "dentmark/common/geometry/rigid_fit.h"

#include <Eigen/SVD>
#include <cmath>

#include "point_set_moments.h"

namespace dentmark {

RigidFit fit_rigid(std::span<const Eigen::Vector3d> from, std::span<const Eigen::Vector3d> to,
                   std::span<const double> weights) {
  if (from.size() != to.size())
    throw GeometryError("fit_rigid: " + std::to_string(from.size()) + " source points but " +
                        std::to_string(to.size()) + " target points");
  const detail::PointSetMoments mf = detail::point_set_moments(from, weights, "fit_rigid (from)");
  const detail::PointSetMoments mt = detail::point_set_moments(to, weights, "fit_rigid (to)");
  if (detail::is_collinear(mf.scatter)) throw GeometryError("fit_rigid: source points are collinear");

  // Cross-covariance H = Σ w (from − c_f)(to − c_t)ᵀ (Arun eq. 11).
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < from.size(); ++i) {
    const double w = weights.empty() ? 1.0 : weights[i];
    h += w * (from[i] - mf.centroid) * (to[i] - mt.centroid).transpose();
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  // R = V diag(1, 1, det(V Uᵀ)) Uᵀ: Umeyama's correction returns the best proper
  // rotation even when noise or coplanar data would make V Uᵀ a reflection.
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  const Eigen::Matrix3d r = svd.matrixV() * d * svd.matrixU().transpose();

  RigidFit fit;
  fit.T_to_from = Transform::Identity();
  fit.T_to_from.linear() = r;
  fit.T_to_from.translation() = mt.centroid - r * mf.centroid;
  double sq = 0.0;
  for (std::size_t i = 0; i < from.size(); ++i) {
    const double w = weights.empty() ? 1.0 : weights[i];
    sq += w * (to[i] - fit.T_to_from * from[i]).squaredNorm();
  }
  fit.rms = std::sqrt(sq / mf.weight_sum);
  fit.count = mf.weighted_count;
  return fit;
}

}  // namespace dentmark
