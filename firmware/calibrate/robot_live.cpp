#include "dentmark/firmware/calibrate/robot_live.h"

#include "dentmark/firmware/calibrate/calibrate_error.h"

namespace dentmark::calibrate {
namespace {

// Fewest usable poses a live calibration accepts: the hold-out figure needs enough
// poses left after each one is taken out.
constexpr int kMinPoses = 6;

Acquisition visit(TargetRig& rig, const std::vector<Transform>& poses, const Transform& home,
                  const PoseProgress& progress) {
  Acquisition a = rig.collect(poses, [&](std::size_t i, const PoseRecord& r) {
    if (progress) progress(i, poses.size(), r);
  });
  rig.move_to(home);
  return a;
}

}  // namespace

LiveCalibration calibrate_robot_live(TargetRig& rig, const ToolTarget& target,
                                     const track::StereoCalibration& stereo, const PosePlanOptions& plan,
                                     const PoseProgress& progress) {
  LiveCalibration live;
  live.T_base_tool_start = rig.connect().T_base_tool;
  const TargetMeasurement first = rig.measure();
  if (!first.found)
    throw CalibrateError("the target is not seen at the robot's current pose (" + first.why +
                         "): jog the robot so that both cameras see the whole target, then start again");
  live.T_base_camL_prior = live.T_base_tool_start * target.T_tool_target * first.T_camL_target.inverse();
  live.planned = plan_calibration_poses(target, stereo, live.T_base_camL_prior, live.T_base_tool_start, plan);
  live.acquisition = visit(rig, live.planned, live.T_base_tool_start, progress);
  const int found = static_cast<int>(live.acquisition.samples.samples.size());
  if (found < kMinPoses || 4 * found < 3 * static_cast<int>(live.planned.size()))
    throw CalibrateError("the target was found at only " + std::to_string(found) + " of " +
                         std::to_string(live.planned.size()) +
                         " poses (need 3 in 4, at least 6): check the light, focus and the target's mount");
  live.fit = fit_robot(live.acquisition.samples);
  return live;
}

LiveVerify verify_robot_live(TargetRig& rig, const ToolTarget& target, const track::StereoCalibration& stereo,
                             const Transform& T_base_camL, const PosePlanOptions& plan, double tolerance_m,
                             const PoseProgress& progress) {
  LiveVerify v;
  const Transform start = rig.connect().T_base_tool;
  v.planned = plan_calibration_poses(target, stereo, T_base_camL, start, plan);
  v.acquisition = visit(rig, v.planned, start, progress);
  v.result = verify_robot_calibration(v.acquisition.samples, T_base_camL, static_cast<int>(v.planned.size()),
                                      tolerance_m);
  return v;
}

}  // namespace dentmark::calibrate
