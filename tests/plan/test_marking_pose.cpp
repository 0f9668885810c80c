#include <gtest/gtest.h>

#include <numbers>
#include <random>

#include "dentmark/firmware/plan/marking_pose.h"

namespace dentmark::plan {
namespace {

Transform random_pose(std::mt19937& rng, double reach) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  return make_transform_rotvec(Eigen::Vector3d(u(rng), u(rng), u(rng)) * 1.5,
                               Eigen::Vector3d(u(rng), u(rng), u(rng)) * reach);
}

TEST(MarkingPose, DefectFrameIsProperAndAlignedWithNormal) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 500; ++i) {
    const Eigen::Vector3d c(u(rng), u(rng), u(rng));
    const Eigen::Vector3d n = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    const Transform T_sls_v = defect_frame(c, n * 3.0);  // scale of the normal must not matter
    EXPECT_TRUE(is_rigid(T_sls_v, 1e-9));
    EXPECT_NEAR((T_sls_v.linear().col(2) - n).norm(), 0.0, 1e-12);
    EXPECT_NEAR((T_sls_v.translation() - c).norm(), 0.0, 1e-15);
  }
  EXPECT_THROW(defect_frame(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()), GeometryError);
  EXPECT_THROW(defect_frame(Eigen::Vector3d(NAN, 0, 0), Eigen::Vector3d::UnitZ()), GeometryError);
}

TEST(MarkingPose, ToolPointsIntoSurfaceFromStandoff) {
  const Transform T_v_tool = tool_in_defect_frame(0.03);
  EXPECT_TRUE(is_rigid(T_v_tool, 1e-12));  // the paper's eq. (5) would fail this: det −1
  EXPECT_NEAR((T_v_tool.linear().col(2) - Eigen::Vector3d(0, 0, -1)).norm(), 0.0, 1e-15);
  // The surface point under the tip is 'standoff' ahead along tool z.
  const Eigen::Vector3d surface_in_tool = T_v_tool.inverse() * Eigen::Vector3d::Zero();
  EXPECT_NEAR((surface_in_tool - Eigen::Vector3d(0, 0, 0.03)).norm(), 0.0, 1e-15);
  EXPECT_THROW(tool_in_defect_frame(-0.01), GeometryError);
}

TEST(MarkingPose, ChainPlacesTipAtStandoffOverMovedDefect) {
  // Property: for any calibration and panel motion, the tip sits exactly 'standoff'
  // along the moved normal from the moved defect centre, and the tool z is the
  // moved inward normal — all expressed in base.
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 300; ++i) {
    MarkingChain chain;
    chain.T_base_camL = random_pose(rng, 3.0);
    chain.T_camL_sls = random_pose(rng, 1.0);
    chain.standoff = 0.01 + 0.04 * std::abs(u(rng));
    const Transform M = random_pose(rng, 0.3);
    const Eigen::Vector3d c_sls(u(rng), u(rng), 1.0 + u(rng));
    const Eigen::Vector3d n_sls = Eigen::Vector3d(u(rng), u(rng), -1.0).normalized();
    const Transform T_base_tool = tool_pose_in_base(chain, M, defect_frame(c_sls, n_sls));

    const Transform T_base_sls = chain.T_base_camL * M * chain.T_camL_sls;
    const Eigen::Vector3d c_base = T_base_sls * c_sls;
    const Eigen::Vector3d n_base = T_base_sls.linear() * n_sls;
    EXPECT_NEAR((T_base_tool.translation() - (c_base + chain.standoff * n_base)).norm(), 0.0, 1e-12);
    EXPECT_NEAR((T_base_tool.linear().col(2) + n_base).norm(), 0.0, 1e-12);
    EXPECT_TRUE(is_rigid(T_base_tool, 1e-9));
  }
}

}  // namespace
}  // namespace dentmark::plan
