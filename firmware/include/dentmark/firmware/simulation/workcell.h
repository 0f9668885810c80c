#pragma once
// The simulated marking workcell (design.md §7, the paper's §V set-up): the tracking
// stereo pair 2.8 m from the line, the door on a sled moving at 0.014 m/s, the robot in
// front of the door, and the SLS that scanned the door at position A. Holds the truth
// (true calibrations, true motion) and what the station believes (calibrations with
// errors drawn like a real calibration's residuals).

#include <cstdint>

#include "dentmark/common/geometry/transform.h"
#include "dentmark/sim/stereo/door_model.h"
#include "dentmark/sim/stereo/panel_motion.h"
#include "dentmark/sim/stereo/stereo_rig.h"

namespace dentmark::simulation {

struct ScenarioOptions {
  char position = 'A';             // where the panel is when marking starts: A (scanned here), B or C
  double yaw = 0.0;                // rad, sled rotated about the vertical axis (paper's θ)
  double line_speed = 0.014;       // m/s
  double position_spacing = 0.27;  // m between A, B and C
  double standoff = 0.03;          // m
  int width = 1280, height = 1024;
  double focal_px = 1740.0;
  double baseline = 0.5;  // m
  double distance = 2.8;  // m, camL to the door
  double fps = 10.0;
  double vibration = 1e-4;                // m
  double calibration_translation = 3e-4;  // m, 1σ per axis of each calibration's error
  double calibration_rotation = 2e-4;     // rad, 1σ per axis, about the working volume's centre
  double robot_accuracy = 3e-4;           // m, robot's absolute accuracy error (fixed offset)
  double robot_repeatability = 5e-5;      // m, 1σ per move
  std::uint64_t seed = 1;
};

struct Workcell {
  sim::stereo::StereoRig rig;
  sim::stereo::DoorModel door;
  sim::stereo::PanelMotion motion;  // true; t = 0 is the scan
  // Where the scan's door frame sits on the rendered door: the scan's panel frame
  // (origin at a corner, y up, z out) in the renderer's panel frame (centre, y down, z in).
  Transform T_door_scanpanel = Transform::Identity();
  Transform T_base_camL_true = Transform::Identity();
  Transform T_camL_sls_true = Transform::Identity();
  Transform T_base_camL_est = Transform::Identity();  // what calibration gave the station
  Transform T_camL_sls_est = Transform::Identity();
  Transform robot_home = Transform::Identity();  // tool pose in base at rest
  Eigen::Vector3d workspace_min = Eigen::Vector3d::Zero(), workspace_max = Eigen::Vector3d::Zero();
  double t_mark = 0.0;  // s after the scan when the panel reaches the marking position
};

// T_sls_scanpanel: the scan's panel frame in the sensor frame (from the scan's truth).
// scan_width, scan_height: the scanned door's size (m).
Workcell make_workcell(const ScenarioOptions& options, const Transform& T_sls_scanpanel, double scan_width,
                       double scan_height);

// True position and outward normal of a scan-frame point, in base, at time t.
struct BasePoint {
  Eigen::Vector3d position;
  Eigen::Vector3d normal;
};
BasePoint true_in_base(const Workcell& cell, const Eigen::Vector3d& p_sls, const Eigen::Vector3d& n_sls,
                       double t);

}  // namespace dentmark::simulation
