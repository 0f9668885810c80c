#pragma once
// The live robot calibration's sample source (docs/calibration.md): the robot carries
// the tool's target to each planned pose over its hal link (Modbus), and once it is at
// rest the stereo pair takes a fresh pair and the target is measured
// (target_measurement.h). The result is the same RobotSamples that `--from-file`
// reads, so one fit (robot_fit.h) serves both sources.

#include <functional>
#include <string>
#include <vector>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/calibrate/robot_fit.h"
#include "dentmark/firmware/calibrate/target_measurement.h"
#include "dentmark/firmware/calibrate/tool_target.h"
#include "dentmark/firmware/hal/camera/camera.h"
#include "dentmark/firmware/hal/robot/robot.h"

namespace dentmark::calibrate {

struct AcquisitionOptions {
  double speed = 0.0;          // m/s, 0: the robot's maximum (the board's limit applies in the robot)
  double move_timeout = 60.0;  // s per move
  double poll_period = 0.02;   // s between status reads (heartbeating)
  double settle = 0.3;         // s at rest before the images are taken (vibration)
  double grab_timeout = 2.0;   // s per frame
  double max_reprojection_px = 2.0;
};

struct PoseRecord {
  Transform T_base_tool = Transform::Identity();  // as the robot reports it at rest
  bool used = false;
  std::string why;  // when not used
  double max_reprojection_px = 0.0;
};

struct Acquisition {
  RobotSamples samples;
  std::vector<PoseRecord> poses;  // one per planned pose, in order
  double robot_seconds = 0.0;     // the robot's own clock from the first move to the last rest
};

// The robot, the target it carries and the stereo pair that looks at it.
class TargetRig {
 public:
  TargetRig(hal::Robot& robot, hal::Camera& left, hal::Camera& right, clock::Clock& clock,
            const track::StereoCalibration& stereo, const ToolTarget& target,
            AcquisitionOptions options = {});

  // Connects and reads the robot's status (its current pose).
  hal::RobotStatus connect();
  // Moves and waits until the robot is at rest there. Throws hal::RobotError.
  hal::RobotStatus move_to(const Transform& T_base_tool);
  // The target measured from a pair taken after the settle time, at the current pose.
  TargetMeasurement measure();
  // Visits every pose in order; 'progress' (may be empty) is told after each.
  Acquisition collect(const std::vector<Transform>& poses,
                      const std::function<void(std::size_t, const PoseRecord&)>& progress = {});

 private:
  cv::Mat fresh_frame(hal::Camera& camera, double not_before);

  hal::Robot& robot_;
  hal::Camera &left_, &right_;
  clock::Clock& clock_;
  const track::StereoCalibration& stereo_;
  ToolTarget target_;
  AcquisitionOptions options_;
};

}  // namespace dentmark::calibrate
