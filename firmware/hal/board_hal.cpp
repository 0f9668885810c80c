#include "dentmark/firmware/hal/board_hal.h"

#include "dentmark/firmware/hal/camera/v4l2_camera.h"
#include "dentmark/firmware/hal/gpio/sim_gpio.h"
#include "dentmark/firmware/hal/robot/modbus_robot.h"
#include "dentmark/firmware/hal/robot/sim_robot.h"
#include "dentmark/sim/robot/robot_simulator.h"
#ifdef DENTMARK_HAVE_GPIOD_V1
#include "dentmark/firmware/hal/gpio/gpiod_gpio.h"
#endif
#ifdef DENTMARK_HAVE_LIBCAMERA
#include "dentmark/firmware/hal/camera/libcamera_camera.h"
#endif

namespace dentmark::hal {

std::shared_ptr<Gpio> make_gpio(const board::BoardConfig& board, const HalChoice& choice,
                                clock::Clock& clock) {
  if (choice.simulate || board.gpio.backend == board::GpioBackend::kSim) {
    if (choice.sim_chip) return choice.sim_chip;
    std::vector<std::string> lines{board.gpio.sprayer_valve.name, board.gpio.estop.name};
    if (!board.gpio.part_present.name.empty()) lines.push_back(board.gpio.part_present.name);
    return std::make_unique<SimGpio>(lines, clock, choice.gpio_record);
  }
#ifdef DENTMARK_HAVE_GPIOD_V1
  return std::make_unique<GpiodGpio>(board.gpio.chip_label);
#else
  throw GpioError(board.source + ": gpio: this build has no Linux GPIO backend for its libgpiod version");
#endif
}

std::unique_ptr<Robot> make_robot(const board::BoardConfig& board, const HalChoice& choice,
                                  clock::Clock& clock) {
  if (choice.simulate) {
    sim::robot::RobotSimConfig cfg;
    cfg.workspace_min = board.limits.workspace_min;
    cfg.workspace_max = board.limits.workspace_max;
    cfg.max_speed = board.limits.max_speed;
    cfg.max_acceleration = board.limits.max_acceleration;
    cfg.heartbeat_timeout = 5.0 * board.modbus.heartbeat_period;
    return std::make_unique<SimRobot>(cfg, clock, std::max(board.modbus.timeout, 0.2));
  }
  return std::make_unique<ModbusRobot>(board.modbus, clock);
}

std::unique_ptr<Camera> make_camera(const board::BoardConfig& board, StereoSide side, const HalChoice& choice,
                                    clock::Clock& clock) {
  const board::CameraConfig& c = board.camera;
  const cv::Size size(c.width, c.height);
  const std::string& where = side == StereoSide::kLeft ? c.left : c.right;
  const auto backend = choice.simulate ? board::CameraBackend::kSim : c.backend;
  switch (backend) {
    case board::CameraBackend::kV4l2:
      return std::make_unique<V4l2Camera>(where, size);
    case board::CameraBackend::kLibcamera:
#ifdef DENTMARK_HAVE_LIBCAMERA
      return std::make_unique<LibcameraCamera>(where, size);
#else
      throw CameraError(board.source + ": camera.backend: libcamera is not built into this binary");
#endif
    case board::CameraBackend::kReplay:
      // One folder holds both sides (camera.left); camera.right may name another.
      return std::make_unique<ReplayCamera>(side == StereoSide::kRight && !c.right.empty() ? c.right : c.left,
                                            side, clock);
    case board::CameraBackend::kSim:
      if (!choice.render) throw CameraError(where + ": simulated camera needs a renderer");
      return std::make_unique<SimCamera>(
          where, size, choice.sim_frame_period,
          side == StereoSide::kRight && choice.render_right ? choice.render_right : choice.render, clock,
          side == StereoSide::kRight ? choice.sim_right_offset : 0.0);
  }
  throw CameraError(board.source + ": camera.backend: unknown backend");
}

}  // namespace dentmark::hal
