#pragma once
// Rigid transforms named by their frames (design.md §2).
//
// A transform T_a_b maps coordinates expressed in frame b into frame a:
//   p_a = T_a_b * p_b,   T_a_c = T_a_b * T_b_c,   T_b_a = T_a_b.inverse().
// Frames used across dentmark: sls, camL, camR, base, tool, v (defect frame).
// All lengths in metres, angles in radians.

#include <Eigen/Geometry>
#include <stdexcept>
#include <string>

namespace dentmark {

using Transform = Eigen::Isometry3d;

// Thrown by geometry routines on degenerate or invalid input (too few points,
// collinear points, non-finite values, mismatched sizes, bad weights).
class GeometryError : public std::invalid_argument {
 public:
  explicit GeometryError(const std::string& what) : std::invalid_argument(what) {}
};

// Builds T from a rotation matrix (must be orthonormal, det +1) and a translation.
Transform make_transform(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation);

// Builds T from a rotation vector (axis * angle, radians) and a translation.
Transform make_transform_rotvec(const Eigen::Vector3d& rotation_vector, const Eigen::Vector3d& translation);

// The rotation vector (axis * angle, angle in [0, pi]) of T's rotation.
Eigen::Vector3d rotation_vector(const Transform& transform);

// Angle in radians of the rotation that takes a's orientation to b's.
double rotation_angle_between(const Transform& a, const Transform& b);

// True when the linear part is a proper rotation within tol and every entry is finite.
bool is_rigid(const Transform& transform, double tol = 1e-9);

}  // namespace dentmark
