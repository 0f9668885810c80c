#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "dentmark/common/geometry/transform.h"

namespace dentmark {
namespace {

TEST(Transform, ChainsByFrameNames) {
  // T_a_c = T_a_b * T_b_c: a point in c reaches a through b.
  const Transform T_a_b =
      make_transform_rotvec(Eigen::Vector3d(0, 0, std::numbers::pi / 2), Eigen::Vector3d(1, 0, 0));
  const Transform T_b_c = make_transform_rotvec(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 2, 0));
  const Eigen::Vector3d p_c(1, 0, 0);
  const Eigen::Vector3d p_a = (T_a_b * T_b_c) * p_c;
  // p_b = (1, 2, 0); rotating 90° about z gives (−2, 1, 0); plus (1, 0, 0).
  EXPECT_NEAR((p_a - Eigen::Vector3d(-1, 1, 0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(((T_a_b.inverse() * p_a) - T_b_c * p_c).norm(), 0.0, 1e-12);
}

TEST(Transform, RotationVectorRoundTrip) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 200; ++i) {
    Eigen::Vector3d axis(u(rng), u(rng), u(rng));
    axis.normalize();
    const double angle = std::abs(u(rng)) * (std::numbers::pi - 1e-6);
    const Transform t = make_transform_rotvec(axis * angle, Eigen::Vector3d(u(rng), u(rng), u(rng)));
    EXPECT_TRUE(is_rigid(t));
    EXPECT_NEAR((rotation_vector(t) - axis * angle).norm(), 0.0, 1e-9);
    EXPECT_NEAR(rotation_angle_between(Transform::Identity(), t), angle, 1e-9);
  }
}

TEST(Transform, RejectsNonRotation) {
  Eigen::Matrix3d m = Eigen::Matrix3d::Identity();
  m(2, 2) = -1.0;  // reflection
  EXPECT_THROW(make_transform(m, Eigen::Vector3d::Zero()), GeometryError);
  EXPECT_THROW(make_transform(2.0 * Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero()), GeometryError);
  EXPECT_THROW(make_transform_rotvec(Eigen::Vector3d(NAN, 0, 0), Eigen::Vector3d::Zero()), GeometryError);
}

TEST(Transform, SmallAnglesStayAccurate) {
  const Transform t = make_transform_rotvec(Eigen::Vector3d(1e-9, 0, 0), Eigen::Vector3d::Zero());
  EXPECT_NEAR(rotation_angle_between(Transform::Identity(), t), 1e-9, 1e-15);
}

}  // namespace
}  // namespace dentmark
