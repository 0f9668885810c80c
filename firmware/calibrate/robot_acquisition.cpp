#include "dentmark/firmware/calibrate/robot_acquisition.h"

#include "dentmark/firmware/calibrate/calibrate_error.h"

namespace dentmark::calibrate {

TargetRig::TargetRig(hal::Robot& robot, hal::Camera& left, hal::Camera& right, clock::Clock& clock,
                     const track::StereoCalibration& stereo, const ToolTarget& target,
                     AcquisitionOptions options)
    : robot_(robot),
      left_(left),
      right_(right),
      clock_(clock),
      stereo_(stereo),
      target_(target),
      options_(options) {}

hal::RobotStatus TargetRig::connect() {
  robot_.connect();
  robot_.heartbeat();
  return robot_.status();
}

hal::RobotStatus TargetRig::move_to(const Transform& T_base_tool) {
  const std::uint16_t seq = robot_.move_to(T_base_tool, options_.speed);
  return robot_.wait_done(seq, options_.move_timeout, options_.poll_period, clock_);
}

// The camera runs only while measuring, so that its first frame is taken now (a
// free-running camera would hand back frames queued during the move).
cv::Mat TargetRig::fresh_frame(hal::Camera& camera, double not_before) {
  camera.start();
  for (int k = 0; k < 50; ++k) {
    robot_.heartbeat();
    std::optional<hal::Frame> f = camera.grab(options_.grab_timeout);
    if (!f) break;
    if (f->time >= not_before) {
      camera.stop();
      return f->image;
    }
  }
  camera.stop();
  throw CalibrateError(camera.name() + ": no frame within " + std::to_string(options_.grab_timeout) + " s");
}

TargetMeasurement TargetRig::measure() {
  const double not_before = clock_.now() + options_.settle;
  while (clock_.now() < not_before) {
    robot_.heartbeat();
    clock_.sleep_until(std::min(not_before, clock_.now() + options_.poll_period));
  }
  const cv::Mat left = fresh_frame(left_, not_before);
  const cv::Mat right = fresh_frame(right_, not_before);
  return measure_target(target_.spec, stereo_, left, right, options_.max_reprojection_px);
}

Acquisition TargetRig::collect(const std::vector<Transform>& poses,
                               const std::function<void(std::size_t, const PoseRecord&)>& progress) {
  Acquisition a;
  a.samples.target_points_tool = target_.points_tool();
  double robot_start = -1.0, robot_end = 0.0;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    if (robot_start < 0.0) robot_start = robot_.status().robot_time;
    const hal::RobotStatus at = move_to(poses[i]);
    PoseRecord r;
    r.T_base_tool = at.T_base_tool;
    const TargetMeasurement m = measure();
    robot_end = robot_.status().robot_time;
    r.used = m.found;
    r.why = m.why;
    r.max_reprojection_px = m.max_reprojection_px;
    if (m.found) a.samples.samples.push_back({at.T_base_tool, m.points_camL});
    a.poses.push_back(r);
    if (progress) progress(i, r);
  }
  a.robot_seconds = std::max(0.0, robot_end - robot_start);
  return a;
}

}  // namespace dentmark::calibrate
