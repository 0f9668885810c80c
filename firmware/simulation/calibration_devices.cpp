#include "dentmark/firmware/simulation/calibration_devices.h"

#include <stdexcept>

#include "dentmark/firmware/hal/board_hal.h"

namespace dentmark::simulation {

std::unique_ptr<CalibrationDevices> open_calibration_devices(
    const board::BoardConfig& board, std::optional<sim::calibration::CalibrationScene> scene,
    clock::Clock& clock, std::function<Transform()> true_tool_pose) {
  auto d = std::make_unique<CalibrationDevices>();
  hal::HalChoice choice;
  d->robot = hal::make_robot(board, choice, clock);
  if (board.camera.backend == board::CameraBackend::kSim) {
    if (!scene)
      throw std::runtime_error(board.source +
                               ": camera.backend is sim: give the twin's scene with --sim-scene FILE");
    d->scene = std::move(scene);
    if (d->scene->rig.size != cv::Size(board.camera.width, board.camera.height))
      throw std::runtime_error("the twin's scene: image size differs from the board's camera.width/height");
    d->renderer = std::make_unique<sim::calibration::ChessboardRenderer>(d->scene->rig, d->scene->target);
    // Where the target truly is: the tool's true pose if known, else the robot's reported
    // pose (an exact robot), through the scene's mount and true T_base_camL.
    auto render = [dev = d.get(), rng = std::make_shared<cv::RNG>(7), true_tool_pose](sim::stereo::Eye eye) {
      const Transform T_base_tool = true_tool_pose ? true_tool_pose() : dev->robot->status().T_base_tool;
      const Transform T_camL_target =
          dev->scene->T_base_camL.inverse() * T_base_tool * dev->scene->T_tool_target;
      return dev->renderer->render(eye, T_camL_target, dev->scene->imaging, *rng);
    };
    choice.render = [render](double) { return render(sim::stereo::Eye::kLeft); };
    choice.render_right = [render](double) { return render(sim::stereo::Eye::kRight); };
  } else if (scene) {
    throw std::runtime_error("--sim-scene: only for a board whose camera.backend is sim");
  }
  d->left = hal::make_camera(board, hal::StereoSide::kLeft, choice, clock);
  d->right = hal::make_camera(board, hal::StereoSide::kRight, choice, clock);
  return d;
}

std::unique_ptr<CalibrationDevices> open_calibration_devices(const board::BoardConfig& board,
                                                             const std::string& sim_scene,
                                                             clock::Clock& clock) {
  std::optional<sim::calibration::CalibrationScene> scene;
  if (!sim_scene.empty()) {
    if (board.camera.backend != board::CameraBackend::kSim)
      throw std::runtime_error("--sim-scene: only for a board whose camera.backend is sim");
    scene = sim::calibration::read_calibration_scene(sim_scene);
    if (scene->rig.size != cv::Size(board.camera.width, board.camera.height))
      throw std::runtime_error(sim_scene + ": image size differs from the board's camera.width/height");
  }
  return open_calibration_devices(board, std::move(scene), clock);
}

}  // namespace dentmark::simulation
