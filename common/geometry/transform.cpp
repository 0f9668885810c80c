#include "dentmark/common/geometry/transform.h"

#include <cmath>

namespace dentmark {

Transform make_transform(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation) {
  Transform t = Transform::Identity();
  t.linear() = rotation;
  t.translation() = translation;
  if (!is_rigid(t, 1e-6)) throw GeometryError("make_transform: rotation is not orthonormal with det +1");
  return t;
}

Transform make_transform_rotvec(const Eigen::Vector3d& rotation_vector, const Eigen::Vector3d& translation) {
  if (!rotation_vector.allFinite() || !translation.allFinite())
    throw GeometryError("make_transform_rotvec: non-finite input");
  const double angle = rotation_vector.norm();
  Transform t = Transform::Identity();
  if (angle > 0.0) t.linear() = Eigen::AngleAxisd(angle, rotation_vector / angle).toRotationMatrix();
  t.translation() = translation;
  return t;
}

Eigen::Vector3d rotation_vector(const Transform& transform) {
  const Eigen::AngleAxisd aa(transform.rotation());
  return aa.axis() * aa.angle();
}

double rotation_angle_between(const Transform& a, const Transform& b) {
  const Eigen::Matrix3d r = a.linear().transpose() * b.linear();
  // acos of (trace − 1)/2 loses precision near 0; atan2 of sin and cos does not.
  const Eigen::Vector3d axis_sin(r(2, 1) - r(1, 2), r(0, 2) - r(2, 0), r(1, 0) - r(0, 1));
  return std::atan2(0.5 * axis_sin.norm(), 0.5 * (r.trace() - 1.0));
}

bool is_rigid(const Transform& transform, double tol) {
  const Eigen::Matrix3d r = transform.linear();
  if (!r.allFinite() || !transform.translation().allFinite()) return false;
  if ((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > tol) return false;
  return std::abs(r.determinant() - 1.0) <= tol;
}

}  // namespace dentmark
