// Backends chosen from the board file (and --sim): the shipped boards give the
// expected devices; the simulated set works end to end.
#include <gtest/gtest.h>

#include "dentmark/firmware/hal/board_hal.h"
#include "dentmark/firmware/hal/camera/sim_camera.h"
#include "dentmark/firmware/hal/robot/modbus_robot.h"

namespace dentmark::hal {
namespace {

board::BoardConfig load(const std::string& b) {
  return board::load_board_config(std::string(DENTMARK_SOURCE_DIR) + "/boards/" + b + "/board.yaml");
}

TEST(BoardHal, SimulatedDevicesFromTheQemuBoard) {
  const auto board = load("qemu/virt-aarch64");
  clock::SimClock clock(5.0);
  HalChoice choice;
  choice.simulate = true;
  choice.render = [&](double) {
    return cv::Mat(board.camera.height, board.camera.width, CV_8UC1, cv::Scalar(9));
  };
  choice.sim_frame_period = 0.05;

  auto gpio = make_gpio(board, choice, clock);
  auto lines = request_board_lines(*gpio, board.gpio);  // the board's line names exist on the simulated chip
  EXPECT_EQ(lines.sprayer_valve->name(), "sprayer-valve");
  EXPECT_FALSE(lines.sprayer_valve->get());

  auto robot = make_robot(board, choice, clock);
  robot->connect();
  const auto target = make_transform_rotvec(Eigen::Vector3d(3.0, 0, 0), Eigen::Vector3d(0.3, 0.1, 0.4));
  const auto s = robot->wait_done(robot->move_to(target, 0.0), 20.0, 0.02, clock);
  EXPECT_LT((s.T_base_tool.translation() - target.translation()).norm(), 1e-4);
  // The board's workspace is the simulator's: z above workspace_max is refused.
  const auto outside = make_transform_rotvec(Eigen::Vector3d(3.0, 0, 0), Eigen::Vector3d(0.3, 0.1, 1.3));
  EXPECT_THROW(robot->wait_done(robot->move_to(outside, 0.0), 5.0, 0.02, clock), RobotError);

  auto left = make_camera(board, StereoSide::kLeft, choice, clock);
  // Simulated whatever the board's backend (v4l2 here), named after the board's device.
  EXPECT_NE(dynamic_cast<SimCamera*>(left.get()), nullptr);
  EXPECT_EQ(left->name(), board.camera.left);
  left->start();
  const auto f = left->grab(1.0);
  ASSERT_TRUE(f.has_value());
  EXPECT_EQ(f->image.size(), cv::Size(640, 480));  // the board's vivid cameras' size
}

TEST(BoardHal, RealBackendsFollowTheBoardFile) {
  clock::MonotonicClock clock;
  const HalChoice real;
  const auto imx = load("nxp/imx8mp-evk");
  EXPECT_EQ(make_camera(imx, StereoSide::kRight, real, clock)->name(), "/dev/video3");
  auto rtu = make_robot(imx, real, clock);
  EXPECT_EQ(dynamic_cast<ModbusRobot&>(*rtu).endpoint(), "modbus rtu /dev/ttymxc1");
  const auto rpi = load("raspberrypi/rpi5");
  auto tcp = make_robot(rpi, real, clock);
  EXPECT_EQ(dynamic_cast<ModbusRobot&>(*tcp).endpoint(), "modbus tcp 192.168.10.20:502");
#ifdef DENTMARK_HAVE_LIBCAMERA
  EXPECT_EQ(make_camera(rpi, StereoSide::kLeft, real, clock)->name(), rpi.camera.left);
#endif
  // No such GPIO chip on a build machine: a clear error naming it, no crash.
  auto gpio = make_gpio(rpi, real, clock);
  try {
    gpio->request_output(rpi.gpio.sprayer_valve, false);
    GTEST_SKIP() << "this machine has a chip labelled " << rpi.gpio.chip_label;
  } catch (const GpioError& e) {
    EXPECT_NE(std::string(e.what()).find("pinctrl-rp1"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace dentmark::hal
