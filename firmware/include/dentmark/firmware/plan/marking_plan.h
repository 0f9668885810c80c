#pragma once
// Orders the defects of one panel for marking while the panel moves, and predicts
// where each defect will be when the tool gets there (design.md §4, planner).
//
// The panel's motion comes in as a predictor M(t) (from the tracker's constant-velocity
// model); the robot is modelled by its speed and acceleration limits. For each
// candidate the interception time t* solves t* = t_free + move_time(tip → target(t*)),
// a fixed point that converges quickly because the line (~0.014 m/s) is far slower
// than the tool (~0.25 m/s). The next defect is the one reachable soonest (greedy).

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "dentmark/firmware/plan/marking_pose.h"

namespace dentmark::plan {

struct RobotLimits {
  Eigen::Vector3d workspace_min = Eigen::Vector3d::Constant(-1.0);  // m, in base
  Eigen::Vector3d workspace_max = Eigen::Vector3d::Constant(1.0);   // m, in base
  double max_speed = 0.25;                                          // m/s
  double max_acceleration = 1.0;                                    // m/s²

  bool contains(const Eigen::Vector3d& p_base) const {
    return (p_base.array() >= workspace_min.array()).all() && (p_base.array() <= workspace_max.array()).all();
  }
};

// Time to move a distance d from rest to rest with a trapezoidal (or triangular) speed profile.
double move_time(double distance, const RobotLimits& limits);

struct PlannerConfig {
  MarkingChain chain;
  RobotLimits limits;
  double spray_duration = 0.15;  // s the tool dwells at the mark
  double horizon = 120.0;        // s: a defect not reachable within this is skipped
  double time_step = 0.25;       // s: search step when waiting for a defect to enter the workspace
};

struct DefectToMark {
  std::uint32_t id = 0;
  Transform T_sls_v = Transform::Identity();  // defect frame in the scan (plan::defect_frame)
};

struct PlannedMark {
  std::uint32_t id = 0;
  bool reachable = false;
  std::string reason;                             // why not, when unreachable
  double t_arrive = 0.0;                          // s, when the tip reaches the pose
  Transform T_base_tool = Transform::Identity();  // predicted pose at t_arrive
};

// Panel motion in camL since the scan: p_camL(t) = M(t) · p_camL(t_scan).
using MotionPredictor = std::function<Transform(double t)>;

// Plans all defects starting with the tip at tip_base at time t_now. Unreachable
// defects come last with reachable == false and a reason.
std::vector<PlannedMark> plan_marks(const std::vector<DefectToMark>& defects, const Eigen::Vector3d& tip_base,
                                    double t_now, const MotionPredictor& motion, const PlannerConfig& config);

}  // namespace dentmark::plan
