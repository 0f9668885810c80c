#pragma once
// The twin's robot-calibration scene: what the simulated cameras see while the robot
// simulator carries the calibration target (docs/calibration.md, "The twin"). It holds
// the ground truth the calibration must recover (T_base_camL) and is read only by the
// renderer, never by the calibration itself.
//
// File (OpenCV FileStorage YAML): the true stereo rig as in stereo.yaml
// (image_width, image_height, K1, D1, K2, D2, R, T), T_base_camL (4×4),
// T_tool_target (4×4: the target on the flange), target_cols, target_rows,
// target_square (m), blur_sigma (px), noise_sigma (grey levels).

#include <filesystem>

#include "dentmark/common/geometry/transform.h"
#include "dentmark/sim/calibration/chessboard_renderer.h"
#include "dentmark/sim/stereo/stereo_rig.h"

namespace dentmark::sim::calibration {

struct CalibrationScene {
  sim::stereo::StereoRig rig;
  Transform T_base_camL = Transform::Identity();    // the truth
  Transform T_tool_target = Transform::Identity();  // the target's mount (as drawn)
  ChessboardTarget target;
  TargetImaging imaging;
};

// Throws std::runtime_error naming the file and field.
CalibrationScene read_calibration_scene(const std::filesystem::path& path);
void write_calibration_scene(const CalibrationScene& scene, const std::filesystem::path& path);

// The station's twin geometry (firmware/simulation/workcell.cpp): camL 2.8 m from the
// door, f = 1740 px, 0.5 m baseline toed in on the door, 1280×1024; robot base 0.6 m in
// front of the door with its axes along camL's; a 7×6 chessboard of 30 mm squares on
// the flange, 20 mm in front of the tool point.
CalibrationScene twin_calibration_scene();

}  // namespace dentmark::sim::calibration
