#pragma once
// The devices `calibrate robot` (live) and `calibrate verify` drive: the board's robot
// and camera pair (hal/board_hal.h). With a board whose cameras are simulated
// (camera.backend: sim) the cameras render the twin's calibration scene
// (sim/calibration, --sim-scene): the tool's target at the pose the robot reports,
// through the scene's true camera rig and T_base_camL, which the calibration never sees.

#include <memory>
#include <optional>
#include <string>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/board/board_config.h"
#include "dentmark/firmware/hal/camera/camera.h"
#include "dentmark/firmware/hal/robot/robot.h"
#include "dentmark/sim/calibration/calibration_scene.h"

namespace dentmark::edge {

struct CalibrationDevices {
  std::unique_ptr<hal::Robot> robot;
  std::unique_ptr<hal::Camera> left, right;
  std::optional<sim::CalibrationScene> scene;  // simulated cameras only
  std::unique_ptr<sim::ChessboardRenderer> renderer;
};

// Throws std::runtime_error (hal errors, a sim board without --sim-scene, a scene whose
// image size differs from the board's).
std::unique_ptr<CalibrationDevices> open_calibration_devices(const board::BoardConfig& board,
                                                             const std::string& sim_scene,
                                                             clock::Clock& clock);

}  // namespace dentmark::edge
