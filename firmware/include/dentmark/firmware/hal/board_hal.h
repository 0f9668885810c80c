#pragma once
// The one place that picks hal backends: from the board file, or all simulated when
// the command line asks for the twin (`--sim`). The daemon's wiring calls these;
// nothing else names a backend.

#include <memory>
#include <string>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/board/board_config.h"
#include "dentmark/firmware/hal/camera/camera.h"
#include "dentmark/firmware/hal/camera/replay_camera.h"
#include "dentmark/firmware/hal/camera/sim_camera.h"
#include "dentmark/firmware/hal/gpio/gpio.h"
#include "dentmark/firmware/hal/robot/robot.h"

namespace dentmark::hal {

struct HalChoice {
  bool simulate = false;    // every device simulated, whatever the board says
  std::string gpio_record;  // simulated GPIO: file recording every edge (empty: memory only)
  // A simulated chip the caller keeps, as gpio-sim's chip outlives the processes that
  // use it (the twin's, across a daemon's kill and restart). Empty: a chip of our own.
  std::shared_ptr<Gpio> sim_chip;
  SimCamera::Render render;        // simulated cameras: renders a frame for a time (required for sim)
  SimCamera::Render render_right;  // the right camera's, when it differs (empty: 'render' for both)
  double sim_frame_period = 0.2;   // s (the paper's 5 Hz)
  double sim_right_offset = 0.0;   // s, right sensor's trigger offset
};

// libgpiod on the board's chip (found by label), or a simulated chip with the board's
// line names (choice.sim_chip when given).
std::shared_ptr<Gpio> make_gpio(const board::BoardConfig& board, const HalChoice& choice,
                                clock::Clock& clock);
// The Modbus robot at the board's endpoint, or the in-process simulator with the board's limits.
std::unique_ptr<Robot> make_robot(const board::BoardConfig& board, const HalChoice& choice,
                                  clock::Clock& clock);
// One camera of the pair, by the board's camera backend (sim when simulating).
std::unique_ptr<Camera> make_camera(const board::BoardConfig& board, StereoSide side, const HalChoice& choice,
                                    clock::Clock& clock);

}  // namespace dentmark::hal
