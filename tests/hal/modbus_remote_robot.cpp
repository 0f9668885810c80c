// ModbusRobot against a robot simulator in another machine, libcamera test style:
// exit 0 pass, 1 fail, 77 skip (no address given). In the QEMU system tests the
// simulator is `dentmark robot-sim` on the host, reached from the guest through QEMU's
// user-mode network (TCP; the host is 10.0.2.2 there) or through a second UART whose
// QEMU chardev is a pty on the host (RTU).
//
// Moves the tool to two poses and checks the robot reports each within 1 mm and
// 1 mrad (the simulator defaults to no accuracy error), sprays once and checks the
// spray count rose by one, and reports the status request round trip.
//
// Usage: modbus_remote_robot HOST:PORT | rtu:DEVICE   (RTU: 115200 8N1, unit 1)
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/hal/robot/modbus_robot.h"

namespace {

using dentmark::Transform;

Transform pose(double x, double y, double z) {
  return dentmark::make_transform_rotvec(Eigen::Vector3d(3.0, 0.0, 0.0), Eigen::Vector3d(x, y, z));
}

struct PoseError {
  double position;  // m
  double rotation;  // rad
};
PoseError error(const Transform& a, const Transform& b) {
  const Transform d = a.inverse() * b;
  return {d.translation().norm(), Eigen::AngleAxisd(d.rotation()).angle()};
}

int run(const std::string& address) {
  dentmark::board::ModbusConfig config;
  const auto colon = address.find(':');
  if (colon == std::string::npos) {
    std::printf("fail: '%s' is neither HOST:PORT nor rtu:DEVICE\n", address.c_str());
    return 2;
  }
  if (address.substr(0, colon) == "rtu") {
    config.transport = dentmark::board::ModbusTransport::kRtu;
    config.device = address.substr(colon + 1);
  } else {
    config.transport = dentmark::board::ModbusTransport::kTcp;
    config.host = address.substr(0, colon);
    config.port = std::stoi(address.substr(colon + 1));
  }
  config.timeout = 1.0;  // s per request: the guest is emulated, on a host that may be busy
  dentmark::clock::MonotonicClock clock;
  dentmark::hal::ModbusRobot robot(config, clock);
  robot.connect();
  std::printf("connected to %s\n", robot.endpoint().c_str());

  std::vector<double> round_trip;
  for (int i = 0; i < 20; ++i) {
    const double t0 = clock.now();
    robot.status();
    round_trip.push_back(clock.now() - t0);
    robot.heartbeat();
  }
  std::sort(round_trip.begin(), round_trip.end());
  std::printf("status request round trip: median %.2f ms, max %.2f ms over %zu\n", 1e3 * round_trip[10],
              1e3 * round_trip.back(), round_trip.size());

  const std::uint32_t sprays = robot.status().spray_count;
  for (const Transform& target : {pose(0.30, 0.10, 0.40), pose(0.25, -0.05, 0.35)}) {
    const double t0 = clock.now();
    const auto done = robot.wait_done(robot.move_to(target, 0.25), 30.0, 0.05, clock);
    const auto [dp, dr] = error(target, done.T_base_tool);
    std::printf("move to (%.3f, %.3f, %.3f) m: done in %.2f s, off by %.3f mm, %.3f mrad\n",
                target.translation().x(), target.translation().y(), target.translation().z(),
                clock.now() - t0, 1e3 * dp, 1e3 * dr);
    if (dp > 1e-3 || dr > 1e-3) {
      std::puts("fail: the robot did not reach the target");
      return 1;
    }
  }
  const auto sprayed = robot.wait_done(robot.spray(0.05), 10.0, 0.05, clock);
  if (sprayed.spray_count != sprays + 1) {
    std::printf("fail: spray count %u -> %u, expected one more\n", sprays, sprayed.spray_count);
    return 1;
  }
  std::puts("pass");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || std::string(argv[1]).empty()) {
    std::puts("skip: no robot address (HOST:PORT); the QEMU system tests give one");
    return 77;
  }
  try {
    return run(argv[1]);
  } catch (const std::exception& e) {
    std::printf("fail: %s\n", e.what());
    return 1;
  }
}
