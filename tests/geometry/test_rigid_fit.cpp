#include <gtest/gtest.h>

#include <numbers>
#include <random>
#include <vector>

#include "dentmark/common/geometry/rigid_fit.h"

namespace dentmark {
namespace {

Transform random_pose(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::Vector3d axis(u(rng), u(rng), u(rng));
  axis.normalize();
  const double angle = std::abs(u(rng)) * std::numbers::pi;
  return make_transform_rotvec(axis * angle, Eigen::Vector3d(u(rng), u(rng), u(rng)) * 3.0);
}

std::vector<Eigen::Vector3d> random_points(std::mt19937& rng, int n, double extent) {
  std::uniform_real_distribution<double> u(-extent, extent);
  std::vector<Eigen::Vector3d> pts(n);
  for (auto& p : pts) p = Eigen::Vector3d(u(rng), u(rng), u(rng));
  return pts;
}

TEST(RigidFit, KnownAnswerQuarterTurn) {
  // Unit square corners plus one off-plane point, turned 90° about z and shifted.
  const std::vector<Eigen::Vector3d> from = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}};
  std::vector<Eigen::Vector3d> to;
  for (const auto& p : from) to.emplace_back(-p.y() + 0.5, p.x() - 0.25, p.z() + 2.0);
  const RigidFit fit = fit_rigid(from, to);
  Eigen::Matrix3d r_expected;
  r_expected << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  EXPECT_NEAR((fit.T_to_from.linear() - r_expected).norm(), 0.0, 1e-12);
  EXPECT_NEAR((fit.T_to_from.translation() - Eigen::Vector3d(0.5, -0.25, 2.0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(fit.rms, 0.0, 1e-12);
  EXPECT_EQ(fit.count, 5u);
}

TEST(RigidFit, RecoversRandomPosesExactly) {
  std::mt19937 rng(1);
  for (int trial = 0; trial < 500; ++trial) {
    const Transform truth = random_pose(rng);
    const auto from = random_points(rng, 3 + trial % 20, 0.5);
    std::vector<Eigen::Vector3d> to;
    for (const auto& p : from) to.push_back(truth * p);
    const RigidFit fit = fit_rigid(from, to);
    EXPECT_TRUE(is_rigid(fit.T_to_from, 1e-9));
    EXPECT_LT(rotation_angle_between(fit.T_to_from, truth), 1e-9) << "trial " << trial;
    EXPECT_LT((fit.T_to_from.translation() - truth.translation()).norm(), 1e-9) << "trial " << trial;
  }
}

TEST(RigidFit, NoiseErrorShrinksLikeOneOverSqrtN) {
  // With isotropic noise s per coordinate on n points spread over ±L, the centroid
  // (hence translation at the centroid) error is ~ s·sqrt(3/n). Check the fit is
  // within 4 sigma of that and the RMS residual estimates the noise.
  std::mt19937 rng(2);
  const double s = 1e-4;
  std::normal_distribution<double> noise(0.0, s);
  for (int n : {10, 100, 1000}) {
    double worst = 0.0;
    for (int trial = 0; trial < 30; ++trial) {
      const Transform truth = random_pose(rng);
      const auto from = random_points(rng, n, 0.5);
      std::vector<Eigen::Vector3d> to;
      for (const auto& p : from)
        to.push_back(truth * p + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
      const RigidFit fit = fit_rigid(from, to);
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      for (const auto& p : from) c += p / n;
      worst = std::max(worst, (fit.T_to_from * c - truth * c).norm());
      if (n >= 100) {
        EXPECT_NEAR(fit.rms, s * std::sqrt(3.0), 0.25 * s * std::sqrt(3.0));
      }
    }
    EXPECT_LT(worst, 4.0 * s * std::sqrt(3.0 / n)) << "n=" << n;
  }
}

TEST(RigidFit, NeverReturnsAReflectionForCoplanarPoints) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    const Transform truth = random_pose(rng);
    std::vector<Eigen::Vector3d> from, to;
    for (int i = 0; i < 6; ++i) {
      from.emplace_back(u(rng), u(rng), 0.0);
      to.push_back(truth * from.back() + Eigen::Vector3d(u(rng), u(rng), u(rng)) * 1e-3);
    }
    const RigidFit fit = fit_rigid(from, to);
    EXPECT_NEAR(fit.T_to_from.linear().determinant(), 1.0, 1e-9);
    EXPECT_LT(rotation_angle_between(fit.T_to_from, truth), 0.02);
  }
}

TEST(RigidFit, WeightsSilenceOutliers) {
  std::mt19937 rng(4);
  const Transform truth = random_pose(rng);
  auto from = random_points(rng, 12, 0.5);
  std::vector<Eigen::Vector3d> to;
  for (const auto& p : from) to.push_back(truth * p);
  to[3] += Eigen::Vector3d(0.2, -0.1, 0.3);  // gross outlier
  std::vector<double> w(from.size(), 1.0);
  const RigidFit unweighted = fit_rigid(from, to, w);
  w[3] = 0.0;
  const RigidFit weighted = fit_rigid(from, to, w);
  EXPECT_GT((unweighted.T_to_from.translation() - truth.translation()).norm(), 1e-3);
  EXPECT_LT((weighted.T_to_from.translation() - truth.translation()).norm(), 1e-12);
  EXPECT_EQ(weighted.count, 11u);
}

TEST(RigidFit, RejectsDegenerateInput) {
  const std::vector<Eigen::Vector3d> two = {{0, 0, 0}, {1, 0, 0}};
  EXPECT_THROW(fit_rigid(two, two), GeometryError);
  const std::vector<Eigen::Vector3d> line = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}};
  EXPECT_THROW(fit_rigid(line, line), GeometryError);
  const std::vector<Eigen::Vector3d> tri = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const std::vector<Eigen::Vector3d> tri_nan = {{0, 0, 0}, {NAN, 0, 0}, {0, 1, 0}};
  EXPECT_THROW(fit_rigid(tri, tri_nan), GeometryError);
  EXPECT_THROW(fit_rigid(tri, line), GeometryError);  // size mismatch
  const std::vector<double> negative = {1.0, -1.0, 1.0};
  EXPECT_THROW(fit_rigid(tri, tri, negative), GeometryError);
  const std::vector<double> too_few = {1.0, 0.0, 1.0};
  EXPECT_THROW(fit_rigid(tri, tri, too_few), GeometryError);
  const std::vector<double> wrong_count = {1.0, 1.0};
  EXPECT_THROW(fit_rigid(tri, tri, wrong_count), GeometryError);
}

}  // namespace
}  // namespace dentmark
