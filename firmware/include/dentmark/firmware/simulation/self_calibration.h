#pragma once
// The twin commissions its station with the station's own calibration code instead of
// drawing calibration errors (docs/calibration.md, "The twin commissions itself"):
//   1. stereo.yaml: `calibrate stereo` (calibrate_stereo_images) on 16 rendered pairs
//      of a 9×6 chessboard of 80 mm squares held at 2.4–3.2 m, tilted up to 0.5 rad;
//   2. robot.yaml: `calibrate robot` live (calibrate_robot_live) against the robot
//      simulator over Modbus TCP, its 7×6 tool target rendered where the simulated
//      tool truly is (the robot's accuracy error and repeatability included; the robot
//      reports its nominal pose), 20 planned poses, using the stereo.yaml of step 1;
//   3. scanner.yaml: `calibrate scanner` (calibrate_scanner_captures) on 3 rendered
//      captures of the sphere target (sim/calibration/sphere_target_scan.h) at the
//      door's scan position, using the stereo.yaml of step 1.
// Each step sees only images, scans and the robot's reports; the truth stays in the
// renderers. The results are cached on disk: steps 1–2 under a key of the rig, the
// true T_base_camL and the robot's configuration, step 3 under that key and the true
// T_camL_sls (which the twin derives from the scanned door's pose, so it changes with
// the sled's yaw). A later run with the same truth copies the files.

#include <filesystem>
#include <string>

#include "dentmark/common/geometry/transform.h"
#include "dentmark/firmware/board/board_config.h"
#include "dentmark/firmware/simulation/workcell.h"
#include "dentmark/sim/robot/robot_simulator.h"

namespace dentmark::simulation {

struct SelfCalibrationResult {
  std::filesystem::path stereo_yaml, robot_yaml, scanner_yaml;
  bool from_cache = false;  // all three were cached
  // Against the truth, for the report: translation (m) and rotation (rad) errors.
  double robot_translation_error = 0.0, robot_rotation_error = 0.0;
  double scanner_translation_error = 0.0, scanner_rotation_error = 0.0;
  double stereo_rms_px = 0.0, robot_holdout_rms_m = 0.0, scanner_holdout_rms_m = 0.0;
};

// Runs (or finds in 'cache_dir') the three calibrations for 'cell'. 'board' is the
// twin's board (its cameras and limits); 'robot' the robot simulator's configuration
// for the scenario. Throws std::runtime_error naming the step that failed.
SelfCalibrationResult self_calibrate(const Workcell& cell, const board::BoardConfig& board,
                                     const sim::robot::RobotSimConfig& robot,
                                     const std::filesystem::path& cache_dir);

// Renders `captures` captures of the sphere target near 'centre' (camL, m) into 'dir':
// scan<N>.ply (sls frame), left<N>.png, right<N>.png, and the target's drawing to
// 'target_yaml'. Shared by the twin's commissioning and the scanner calibration's test.
void render_scanner_captures(const sim::stereo::StereoRig& rig, const Transform& T_camL_sls,
                             const Eigen::Vector3d& centre, int captures, std::uint64_t seed,
                             const std::filesystem::path& dir, const std::filesystem::path& target_yaml);

}  // namespace dentmark::simulation
