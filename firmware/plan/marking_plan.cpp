#include "dentmark/firmware/plan/marking_plan.h"

#include <cmath>
#include <limits>
#include <optional>

namespace dentmark::plan {

double move_time(double distance, const RobotLimits& limits) {
  const double v = limits.max_speed, a = limits.max_acceleration;
  if (distance <= 0.0) return 0.0;
  // Triangular profile when the tool never reaches full speed (d ≤ v²/a).
  if (distance <= v * v / a) return 2.0 * std::sqrt(distance / a);
  return distance / v + v / a;
}

namespace {

struct Intercept {
  double t_arrive;
  Transform T_base_tool;
};

// Earliest time ≥ t_free at which the tool, leaving 'tip' at t_free, meets the defect
// inside the workspace; nullopt when none within the horizon.
std::optional<Intercept> intercept(const DefectToMark& d, const Eigen::Vector3d& tip, double t_free,
                                   const MotionPredictor& motion, const PlannerConfig& cfg) {
  for (double t_leave = t_free; t_leave <= t_free + cfg.horizon; t_leave += cfg.time_step) {
    double t = t_leave;
    Transform pose = tool_pose_in_base(cfg.chain, motion(t), d.T_sls_v);
    // Fixed point t = t_leave + move_time(|tip − target(t)|): a contraction while the
    // panel is slower than the tool.
    for (int it = 0; it < 20; ++it) {
      const double t_next = t_leave + move_time((pose.translation() - tip).norm(), cfg.limits);
      pose = tool_pose_in_base(cfg.chain, motion(t_next), d.T_sls_v);
      const bool converged = std::abs(t_next - t) < 1e-4;
      t = t_next;
      if (converged) break;
    }
    if (cfg.limits.contains(pose.translation())) return Intercept{t, pose};
  }
  return std::nullopt;
}

}  // namespace

std::vector<PlannedMark> plan_marks(const std::vector<DefectToMark>& defects, const Eigen::Vector3d& tip_base,
                                    double t_now, const MotionPredictor& motion,
                                    const PlannerConfig& config) {
  std::vector<PlannedMark> plan;
  std::vector<PlannedMark> unreachable;
  std::vector<bool> done(defects.size(), false);
  Eigen::Vector3d tip = tip_base;
  double t_free = t_now;
  for (std::size_t round = 0; round < defects.size(); ++round) {
    std::optional<Intercept> best;
    std::size_t best_i = 0;
    for (std::size_t i = 0; i < defects.size(); ++i) {
      if (done[i]) continue;
      const auto hit = intercept(defects[i], tip, t_free, motion, config);
      if (!hit) {
        done[i] = true;
        unreachable.push_back(PlannedMark{defects[i].id, false, "outside the workspace within the horizon",
                                          0.0, Transform::Identity()});
        continue;
      }
      if (!best || hit->t_arrive < best->t_arrive) {
        best = hit;
        best_i = i;
      }
    }
    if (!best) break;
    done[best_i] = true;
    plan.push_back(PlannedMark{defects[best_i].id, true, "", best->t_arrive, best->T_base_tool});
    tip = best->T_base_tool.translation();
    t_free = best->t_arrive + config.spray_duration;
  }
  plan.insert(plan.end(), unreachable.begin(), unreachable.end());
  return plan;
}

}  // namespace dentmark::plan
