#include "dentmark/firmware/track/plane_view.h"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <vector>

namespace dentmark::track {

std::optional<Eigen::Vector3d> plane_normal(std::span<const Eigen::Vector3d> points) {
  if (points.size() < 3) return std::nullopt;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& p : points) c += p;
  c /= static_cast<double>(points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : points) cov += (p - c) * (p - c).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  if (!(eig.eigenvalues()(1) > 1e-3 * eig.eigenvalues()(2))) return std::nullopt;  // a line
  return Eigen::Vector3d(eig.eigenvectors().col(0));
}

std::optional<cv::Matx22d> plane_view_change(const StereoCalibration& calib, const Eigen::Vector3d& x,
                                             const Eigen::Vector3d& n, Cam from_cam, Cam to_cam,
                                             const Transform& motion) {
  // Two directions in the plane, about a pixel long at the point, seen by both views:
  // finite differences of the full projection (distortion included).
  const Eigen::Vector3d a =
      (std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY()).cross(n).normalized();
  const Eigen::Vector3d b = n.cross(a);
  const double step = x.z() / calib.left.K(0, 0);
  const std::vector<Eigen::Vector3d> before{x, x + step * a, x + step * b};
  const std::vector<Eigen::Vector3d> after{motion * before[0], motion * before[1], motion * before[2]};
  const auto p0 = calib.project(from_cam, before), p1 = calib.project(to_cam, after);
  const cv::Matx22d j0(p0[1].x - p0[0].x, p0[2].x - p0[0].x, p0[1].y - p0[0].y, p0[2].y - p0[0].y);
  const cv::Matx22d j1(p1[1].x - p1[0].x, p1[2].x - p1[0].x, p1[1].y - p1[0].y, p1[2].y - p1[0].y);
  if (std::abs(cv::determinant(j0)) < 1e-6 || std::abs(cv::determinant(j1)) < 1e-6) return std::nullopt;
  return cv::Matx22d(j1 * j0.inv());
}

}  // namespace dentmark::track
