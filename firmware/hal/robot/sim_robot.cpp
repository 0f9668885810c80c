#include "dentmark/firmware/hal/robot/sim_robot.h"

#include "dentmark/sim/robot/robot_simulator.h"

namespace dentmark::hal {

SimRobot::SimRobot(const sim::robot::RobotSimConfig& config, clock::Clock& clock, double request_timeout)
    : sim_(sim::robot::RobotSimulator::serve_tcp(config, clock, "127.0.0.1", 0)) {
  board::ModbusConfig m;
  m.transport = board::ModbusTransport::kTcp;
  m.host = "127.0.0.1";
  m.port = sim_->port();
  m.unit_id = config.unit_id;
  m.timeout = request_timeout;
  client_ = std::make_unique<ModbusRobot>(m, clock);
}

// The client disconnects before the simulator it talks to stops.
SimRobot::~SimRobot() = default;

}  // namespace dentmark::hal
