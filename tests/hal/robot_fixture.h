#pragma once
// Shared setup for the Modbus robot tests: the simulator in-process on a fast clock.

#include <memory>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/board/board_config.h"
#include "dentmark/firmware/hal/robot/modbus_robot.h"
#include "dentmark/sim/robot/robot_simulator.h"

namespace dentmark::test {

// Simulated seconds per real second. Modest so that heartbeats keep up under
// qemu-user, where every request costs more real time.
inline constexpr double kRate = 5.0;

inline sim::robot::RobotSimConfig sim_config() {
  sim::robot::RobotSimConfig c;
  c.heartbeat_timeout = 1.0;  // s (simulated) = 0.2 s real at kRate
  return c;
}

inline board::ModbusConfig tcp_config(int port) {
  board::ModbusConfig m;
  m.transport = board::ModbusTransport::kTcp;
  m.host = "127.0.0.1";
  m.port = port;
  m.timeout = 0.5;  // real seconds
  return m;
}

inline Transform pose(double x, double y, double z, double rx = 3.0, double ry = 0.0, double rz = 0.0) {
  return make_transform_rotvec(Eigen::Vector3d(rx, ry, rz), Eigen::Vector3d(x, y, z));
}

}  // namespace dentmark::test
