#pragma once
// The robot as the edge sees it (design.md §5): send a target pose, spray, abort,
// keep a heartbeat going, read the status block. Backends: Modbus TCP/RTU
// (modbus_robot.h) and the in-process simulator behind the same Modbus path
// (sim_robot.h). The register map is docs/robot-modbus.md.

#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>

#include "dentmark/common/clock/clock.h"
#include "dentmark/common/geometry/transform.h"
#include "dentmark/common/robot_link/register_map.h"

namespace dentmark::hal {

class RobotError : public std::runtime_error {
 public:
  enum class Kind {
    kTimeout,       // no reply within the request timeout (after one reconnect and retry)
    kDisconnected,  // link down and reconnecting failed
    kException,     // the robot answered with a Modbus exception
    kRejected,      // the robot rejected the command (status state kFault)
    kStopped,       // the robot stopped (abort, heartbeat loss)
    kWaitTimeout,   // the command did not finish within the caller's deadline
  };
  RobotError(Kind kind, const std::string& what) : std::runtime_error(what), kind_(kind) {}
  Kind kind() const { return kind_; }

 private:
  Kind kind_;
};

struct RobotStatus {
  std::uint16_t sequence = 0;  // last command the robot took
  robot_link::State state = robot_link::State::kIdle;
  std::uint16_t faults = 0;  // robot_link::fault bits
  std::uint16_t heartbeat = 0;
  Transform T_base_tool = Transform::Identity();  // the robot's own (nominal) tool pose
  std::uint32_t spray_count = 0;
  double robot_time = 0.0;  // s, robot's clock (wraps every 2^32 ms)
  double tool_speed = 0.0;  // m/s
  double read_time = 0.0;   // s, our clock, when the reply arrived
};

class Robot {
 public:
  virtual ~Robot() = default;
  // Opens the link (no-op when open) and sends a first heartbeat.
  virtual void connect() = 0;
  virtual void disconnect() = 0;
  virtual bool connected() const = 0;
  // Each command returns its sequence number; it is done when status().sequence
  // equals it and the state is idle. speed 0 = the robot's maximum.
  virtual std::uint16_t move_to(const Transform& T_base_tool, double speed) = 0;
  virtual std::uint16_t spray(double duration) = 0;
  virtual std::uint16_t abort() = 0;
  // Clears a latched fault or stop (Command::kIdle with a new sequence).
  virtual std::uint16_t reset() = 0;
  // Changes the heartbeat register; call at least every heartbeat period.
  virtual void heartbeat() = 0;
  virtual RobotStatus status() = 0;

  // Polls status every 'period' (heartbeating as it goes) until command 'sequence' is
  // done; returns that status. Throws RobotError kRejected / kStopped when the robot
  // refuses or stops it, kWaitTimeout past 'timeout' seconds of 'clock' time.
  // 'on_status' (may be empty) sees every status read before the command's own checks:
  // the caller's interlocks (e-stop, cancel, a stop before the robot took the
  // command); what it throws ends the wait.
  RobotStatus wait_done(std::uint16_t sequence, double timeout, double period, clock::Clock& clock,
                        const std::function<void(const RobotStatus&)>& on_status = {});
};

}  // namespace dentmark::hal
