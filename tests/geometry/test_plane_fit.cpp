#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "dentmark/common/geometry/plane_fit.h"

namespace dentmark {
namespace {

TEST(PlaneFit, KnownAnswerTiltedPlane) {
  // z = 0.5 x − 0.25 y + 1 sampled on a grid: normal ∝ (−0.5, 0.25, 1).
  std::vector<Eigen::Vector3d> pts;
  for (int i = -3; i <= 3; ++i)
    for (int j = -3; j <= 3; ++j)
      pts.emplace_back(i * 0.01, j * 0.01, 0.5 * i * 0.01 - 0.25 * j * 0.01 + 1.0);
  const Plane plane = fit_plane(pts, {}, Eigen::Vector3d::UnitZ());
  const Eigen::Vector3d expected = Eigen::Vector3d(-0.5, 0.25, 1.0).normalized();
  EXPECT_NEAR((plane.normal - expected).norm(), 0.0, 1e-12);
  EXPECT_NEAR((plane.centroid - Eigen::Vector3d(0, 0, 1)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(plane.rms, 0.0, 1e-12);
  EXPECT_NEAR(plane.signed_distance(Eigen::Vector3d(0, 0, 1) + 0.003 * expected), 0.003, 1e-12);
}

TEST(PlaneFit, HintOrientsNormal) {
  const std::vector<Eigen::Vector3d> pts = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
  EXPECT_GT(fit_plane(pts, {}, Eigen::Vector3d(0, 0, 1)).normal.z(), 0.999);
  EXPECT_LT(fit_plane(pts, {}, Eigen::Vector3d(0, 0, -1)).normal.z(), -0.999);
}

TEST(PlaneFit, RandomPlanesWithNoise) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double s = 2e-5;  // 20 µm, an SLS's noise
  std::normal_distribution<double> noise(0.0, s);
  for (int trial = 0; trial < 200; ++trial) {
    Eigen::Vector3d n(u(rng), u(rng), u(rng));
    n.normalize();
    const Eigen::Vector3d a = n.unitOrthogonal(), b = n.cross(a);
    const Eigen::Vector3d c(u(rng), u(rng), u(rng));
    std::vector<Eigen::Vector3d> pts;
    for (int i = 0; i < 400; ++i) pts.push_back(c + 0.015 * (u(rng) * a + u(rng) * b) + noise(rng) * n);
    const Plane plane = fit_plane(pts, {}, n);
    // Tilt error of a 30 mm patch with 400 points: ~ s / (extent·sqrt(n)) ≈ 1e-4 rad.
    EXPECT_LT((plane.normal - n).norm(), 1e-3) << trial;
    EXPECT_NEAR(plane.rms, s, 0.2 * s);
  }
}

TEST(PlaneFit, RejectsDegenerateInput) {
  const std::vector<Eigen::Vector3d> line = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {3, 3, 3}};
  EXPECT_THROW(fit_plane(line), GeometryError);
  const std::vector<Eigen::Vector3d> same = {{1, 2, 3}, {1, 2, 3}, {1, 2, 3}};
  EXPECT_THROW(fit_plane(same), GeometryError);
  const std::vector<Eigen::Vector3d> two = {{0, 0, 0}, {1, 0, 0}};
  EXPECT_THROW(fit_plane(two), GeometryError);
  const std::vector<Eigen::Vector3d> inf = {{0, 0, 0}, {1, 0, 0}, {0, INFINITY, 0}};
  EXPECT_THROW(fit_plane(inf), GeometryError);
}

}  // namespace
}  // namespace dentmark
