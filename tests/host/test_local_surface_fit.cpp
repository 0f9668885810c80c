// The robust local surface fit of coarse scans (local_surface_fit.h) and the coherent
// vertex groups built on it (coarse_defects.h), against closed-form answers.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "../../host/detect/coarse_defects.h"
#include "../../host/detect/local_surface_fit.h"
#include "dentmark/common/ingest/mesh.h"
#include "detect_scans.h"

namespace dentmark::detect {
namespace {

// w = a + b x + c y + d x² + e xy + f y², a panel patch 3 mm high over 30 mm, sloping.
double quadratic(double x, double y) {
  return 0.003 + 0.2 * x - 0.1 * y + 1.5 * x * x + 0.8 * x * y - 0.6 * y * y;
}

// The ring of a 5 mm grid from 8 to 30 mm round (0, 0), heights on 'quadratic'.
std::vector<Eigen::Vector3d> ring_on_quadratic() {
  std::vector<Eigen::Vector3d> ring;
  for (int i = -6; i <= 6; ++i)
    for (int j = -6; j <= 6; ++j) {
      const double x = 0.005 * i, y = 0.005 * j, r = std::hypot(x, y);
      if (r >= 0.008 && r <= 0.030) ring.emplace_back(x, y, quadratic(x, y));
    }
  return ring;
}

LocalFitOptions annulus() {
  LocalFitOptions o;
  o.inner_radius = 0.008;
  o.outer_radius = 0.030;
  return o;
}

TEST(RobustQuadraticResidual, IsTheOffsetAlongTheNormalOfAQuadratic) {
  // The vertex stands h above the surface along w; along the normal that is h times the
  // cosine of the slope at (0, 0): 1 / sqrt(1 + 0.2² + 0.1²).
  const double h = 0.002;
  const double r = robust_quadratic_residual(quadratic(0, 0) + h, ring_on_quadratic(), annulus());
  EXPECT_NEAR(r, h / std::sqrt(1.0 + 0.04 + 0.01), 1e-9);
}

TEST(RobustQuadraticResidual, GivesNoWeightToAWallOrADefectInTheRing) {
  // A third of the ring 15 mm up (a handle's side) and two samples 5 mm down (a dent): the
  // biweight leaves them out and the residual is the clean one.
  std::vector<Eigen::Vector3d> ring = ring_on_quadratic();
  int moved = 0;
  for (auto& p : ring)
    if (p.x() > 0.012) p.z() += 0.015, ++moved;
  ring[0].z() -= 0.005, ring[1].z() -= 0.005;
  ASSERT_GT(3 * moved, static_cast<int>(ring.size()) / 5);
  const double r = robust_quadratic_residual(quadratic(0, 0) + 0.001, ring, annulus());
  EXPECT_NEAR(r, 0.001 / std::sqrt(1.05), 1e-9);
}

TEST(RobustQuadraticResidual, UnderNoiseIsUnbiasedWithinItsStandardError) {
  // 0.3 mm of Gaussian noise on ~100 ring samples: the fit's value at the centre has a
  // standard error of about 0.3 mm × sqrt(6 / 100) ≈ 0.07 mm; over 200 rings the mean
  // residual of a vertex 2 mm up is 2 mm / cos within 4 standard errors of the mean.
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, 3e-4);
  double sum = 0.0;
  const int n = 200;
  for (int k = 0; k < n; ++k) {
    std::vector<Eigen::Vector3d> ring = ring_on_quadratic();
    for (auto& p : ring) p.z() += noise(rng);
    sum += robust_quadratic_residual(quadratic(0, 0) + 0.002, ring, annulus());
  }
  EXPECT_NEAR(sum / n, 0.002 / std::sqrt(1.05), 4.0 * 7e-5 / std::sqrt(n) + 1e-5);
}

TEST(RobustQuadraticResidual, TooFewPointsGiveNoFit) {
  std::vector<Eigen::Vector3d> ring = ring_on_quadratic();
  ring.resize(5);
  EXPECT_TRUE(std::isnan(robust_quadratic_residual(0.0, ring, annulus())));
}

// A 41 x 41 grid 5 mm apart on a tilted plane w = 0.1 x + 0.05 y, meshed.
ingest::Mesh plane_grid(int n) {
  ingest::Mesh mesh;
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      const float x = 0.005f * static_cast<float>(c), y = 0.005f * static_cast<float>(r);
      mesh.vertices.emplace_back(x, y, 0.1f * x + 0.05f * y);
    }
  detect_test::add_grid_triangles(mesh, n, n);
  return mesh;
}

TEST(LocalSurfaceResiduals, FindALiftedVertexAndLeaveItsNeighboursOnThePlane) {
  const int n = 41;
  ingest::Mesh mesh = plane_grid(n);
  const std::size_t lifted = 20 * n + 20;
  mesh.vertices[lifted].z() += 0.004f;
  LocalFitOptions o;
  o.inner_radius = 1.6 * 0.005;
  o.outer_radius = 6.0 * 0.005;
  const std::vector<float> r = local_surface_residuals(mesh.vertices, o);
  const double cos_slope = 1.0 / std::sqrt(1.0 + 0.01 + 0.0025);
  EXPECT_NEAR(r[lifted], 0.004 * cos_slope, 1e-6);
  for (const std::size_t k : {lifted - 1, lifted + 1, lifted - n, lifted + n, lifted + 2 * n + 3})
    EXPECT_NEAR(r[k], 0.0, 1e-6) << k;
}

TEST(CoherentGroups, ATwoVertexDefectIsAGroupAndALoneVertexIsNot) {
  // Residuals given directly, σ = 1: a pair of neighbours at 6 and 4 σ (a defect over
  // two samples), a lone vertex at 30 σ (a thrown sample), a pair at 4 and 4 σ (no
  // vertex over the detection threshold), and a pair of opposite signs.
  const int n = 11;
  ingest::Mesh mesh = plane_grid(n);
  std::vector<float> residual(mesh.vertices.size(), 0.0f);
  const auto at = [&](int r, int c) { return static_cast<std::size_t>(r * n + c); };
  residual[at(2, 2)] = 6.0f, residual[at(2, 3)] = 4.0f;
  residual[at(8, 8)] = 30.0f;
  residual[at(5, 2)] = 4.0f, residual[at(5, 3)] = 4.0f;
  residual[at(8, 2)] = -6.0f, residual[at(8, 3)] = 6.0f;
  std::vector<std::uint8_t> excluded(mesh.vertices.size(), 0);
  const std::vector<VertexGroup> groups = coherent_groups(mesh, residual, excluded, 1.0, 5.5, 3.0);
  ASSERT_EQ(groups.size(), 1u);
  EXPECT_EQ(groups[0].apex, at(2, 2));
  EXPECT_EQ(groups[0].sign, 1);
  EXPECT_EQ(groups[0].vertices.size(), 2u);
  // On an excluded vertex (a design feature's), the same pair is no group.
  excluded[at(2, 3)] = 1;
  EXPECT_TRUE(coherent_groups(mesh, residual, excluded, 1.0, 5.5, 3.0).empty());
}

TEST(CoarseFinding, IsCentredOnTheGroupsResidualsWithTheApexHeight) {
  const int n = 11;
  ingest::Mesh mesh = plane_grid(n);
  std::vector<float> residual(mesh.vertices.size(), 0.0f);
  residual[5 * n + 5] = -0.003f, residual[5 * n + 6] = -0.001f;
  const VertexGroup g{{static_cast<std::uint32_t>(5 * n + 5), static_cast<std::uint32_t>(5 * n + 6)},
                      static_cast<std::uint32_t>(5 * n + 5),
                      -1};
  const Finding f =
      coarse_finding(g, ingest::MeshView(mesh), residual, Eigen::Vector3d::UnitZ(), 0.005, 3e-4, 5.5);
  EXPECT_EQ(f.defect.defect_class, protocol::DefectClass::kDent);
  EXPECT_DOUBLE_EQ(f.defect.height, static_cast<double>(-0.003f));
  // x: (3 × 25 mm + 1 × 30 mm) / 4 = 26.25 mm.
  EXPECT_NEAR(f.defect.position.x(), 0.02625, 1e-6);
  EXPECT_NEAR(f.defect.position.y(), 0.025, 1e-6);
  // One vertex over half the height: 4 × 5 mm × sqrt(1 / π).
  EXPECT_NEAR(f.defect.diameter, 0.02 / std::sqrt(std::numbers::pi), 1e-9);
}

}  // namespace
}  // namespace dentmark::detect
