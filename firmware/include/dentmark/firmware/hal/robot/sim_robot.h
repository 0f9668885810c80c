#pragma once
// The simulated robot backend: the robot simulator (sim/robot) in this process on a
// loopback port, driven through the same Modbus client as the real robot, so the
// twin exercises the real protocol path. The simulator stays private to the HAL:
// code that uses the HAL neither includes nor links it.

#include <memory>

#include "dentmark/firmware/hal/robot/modbus_robot.h"

namespace dentmark::sim::robot {
struct RobotSimConfig;
class RobotSimulator;
}  // namespace dentmark::sim::robot

namespace dentmark::hal {

class SimRobot final : public Robot {
 public:
  SimRobot(const sim::robot::RobotSimConfig& config, clock::Clock& clock, double request_timeout = 0.5);
  ~SimRobot() override;
  void connect() override { client_->connect(); }
  void disconnect() override { client_->disconnect(); }
  bool connected() const override { return client_->connected(); }
  std::uint16_t move_to(const Transform& T_base_tool, double speed) override {
    return client_->move_to(T_base_tool, speed);
  }
  std::uint16_t spray(double duration) override { return client_->spray(duration); }
  std::uint16_t abort() override { return client_->abort(); }
  std::uint16_t reset() override { return client_->reset(); }
  void heartbeat() override { client_->heartbeat(); }
  RobotStatus status() override { return client_->status(); }

 private:
  std::unique_ptr<sim::robot::RobotSimulator> sim_;
  std::unique_ptr<ModbusRobot> client_;
};

}  // namespace dentmark::hal
