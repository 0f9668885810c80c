#include <gtest/gtest.h>

#include <cmath>

#include "dentmark/firmware/plan/marking_plan.h"

namespace dentmark::plan {
namespace {

// The panel translates along camL x at the line speed.
MotionPredictor line_motion(double speed) {
  return [speed](double t) {
    Transform m = Transform::Identity();
    m.translation() = Eigen::Vector3d(speed * t, 0, 0);
    return m;
  };
}

PlannerConfig config() {
  PlannerConfig c;
  c.limits.workspace_min = Eigen::Vector3d(-1, -1, -1);
  c.limits.workspace_max = Eigen::Vector3d(1, 1, 1);
  c.limits.max_speed = 0.25;
  c.limits.max_acceleration = 1.0;
  c.chain.standoff = 0.03;
  return c;
}

DefectToMark defect(std::uint32_t id, double x, double y) {
  return DefectToMark{id, defect_frame(Eigen::Vector3d(x, y, 0), Eigen::Vector3d::UnitZ())};
}

TEST(MarkingPlan, MoveTimeProfiles) {
  RobotLimits l;
  l.max_speed = 0.25;
  l.max_acceleration = 1.0;
  EXPECT_DOUBLE_EQ(move_time(0.0, l), 0.0);
  EXPECT_NEAR(move_time(0.04, l), 2.0 * std::sqrt(0.04), 1e-12);  // triangular
  EXPECT_NEAR(move_time(1.0, l), 1.0 / 0.25 + 0.25, 1e-12);       // trapezoidal
  // Continuous at the switch-over distance v²/a.
  EXPECT_NEAR(move_time(0.0625 - 1e-12, l), move_time(0.0625 + 1e-12, l), 1e-6);
}

TEST(MarkingPlan, ToolMeetsTheMovingDefect) {
  const PlannerConfig cfg = config();
  const auto motion = line_motion(0.014);
  const std::vector<DefectToMark> defects = {defect(1, 0.2, 0.0)};
  const auto plan = plan_marks(defects, Eigen::Vector3d(0, 0, 0.5), 0.0, motion, cfg);
  ASSERT_EQ(plan.size(), 1u);
  ASSERT_TRUE(plan[0].reachable);
  // At t_arrive the tip is at standoff above where the defect is *then*.
  const Eigen::Vector3d expected(0.2 + 0.014 * plan[0].t_arrive, 0.0, 0.03);
  EXPECT_NEAR((plan[0].T_base_tool.translation() - expected).norm(), 0.0, 1e-6);
  // And the arrival time is consistent with the robot's limits.
  const double d = (expected - Eigen::Vector3d(0, 0, 0.5)).norm();
  EXPECT_NEAR(plan[0].t_arrive, move_time(d, cfg.limits), 1e-3);
}

TEST(MarkingPlan, GreedyOrderVisitsEveryReachableDefectOnce) {
  const PlannerConfig cfg = config();
  const std::vector<DefectToMark> defects = {defect(1, 0.5, 0.0), defect(2, 0.1, 0.0), defect(3, 0.3, 0.1)};
  const auto plan = plan_marks(defects, Eigen::Vector3d(0, 0, 0.1), 0.0, line_motion(0.0), cfg);
  ASSERT_EQ(plan.size(), 3u);
  EXPECT_EQ(plan[0].id, 2u);
  EXPECT_EQ(plan[1].id, 3u);
  EXPECT_EQ(plan[2].id, 1u);
  for (std::size_t i = 1; i < plan.size(); ++i)
    EXPECT_GE(plan[i].t_arrive, plan[i - 1].t_arrive + cfg.spray_duration - 1e-9);
}

TEST(MarkingPlan, WaitsForDefectToEnterWorkspaceOrSkipsIt) {
  PlannerConfig cfg = config();
  cfg.limits.workspace_min = Eigen::Vector3d(0.0, -1, -1);
  cfg.horizon = 60.0;
  // Starts at x = −0.1: outside; the line brings it in after ~7 s.
  const std::vector<DefectToMark> defects = {defect(7, -0.1, 0.0), defect(8, -5.0, 0.0)};
  const auto plan = plan_marks(defects, Eigen::Vector3d(0.1, 0, 0.1), 0.0, line_motion(0.014), cfg);
  ASSERT_EQ(plan.size(), 2u);
  EXPECT_EQ(plan[0].id, 7u);
  EXPECT_TRUE(plan[0].reachable);
  EXPECT_GE(plan[0].T_base_tool.translation().x(), 0.0);
  EXPECT_GT(plan[0].t_arrive, 0.1 / 0.014 - 0.5);
  EXPECT_EQ(plan[1].id, 8u);  // would need ~360 s
  EXPECT_FALSE(plan[1].reachable);
  EXPECT_FALSE(plan[1].reason.empty());
}

}  // namespace
}  // namespace dentmark::plan
