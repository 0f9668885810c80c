#pragma once
// The devices `calibrate robot` (live) and `calibrate verify` drive: the board's robot
// and camera pair (hal/board_hal.h). With a board whose cameras are simulated
// (camera.backend: sim) the cameras render the twin's calibration scene
// (sim/calibration): the tool's target at the pose the robot reports, through the
// scene's true camera rig and T_base_camL, which the calibration never sees. Used by the
// calibrate commands (--sim-scene) and by the twin commissioning itself
// (self_calibration.h).

#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/board/board_config.h"
#include "dentmark/firmware/hal/camera/camera.h"
#include "dentmark/firmware/hal/robot/robot.h"
#include "dentmark/sim/calibration/calibration_scene.h"

namespace dentmark::simulation {

struct CalibrationDevices {
  std::unique_ptr<hal::Robot> robot;
  std::unique_ptr<hal::Camera> left, right;
  std::optional<sim::calibration::CalibrationScene> scene;  // simulated cameras only
  std::unique_ptr<sim::calibration::ChessboardRenderer> renderer;
};

// Throws std::runtime_error (hal errors, a sim board without a scene, a scene with a real
// camera backend, a scene whose image size differs from the board's).
// true_tool_pose, when given, says where the simulated tool truly is (the robot
// simulator's pose with its accuracy error and repeatability); the target is rendered
// there instead of at the pose the robot reports.
std::unique_ptr<CalibrationDevices> open_calibration_devices(
    const board::BoardConfig& board, std::optional<sim::calibration::CalibrationScene> scene,
    clock::Clock& clock, std::function<Transform()> true_tool_pose = {});
// The same with the scene read from a file (--sim-scene; empty: none).
std::unique_ptr<CalibrationDevices> open_calibration_devices(const board::BoardConfig& board,
                                                             const std::string& sim_scene,
                                                             clock::Clock& clock);

}  // namespace dentmark::simulation
