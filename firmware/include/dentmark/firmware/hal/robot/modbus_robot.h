#pragma once
// Robot over Modbus TCP or RTU with libmodbus (docs/robot-modbus.md).
//
// Link policy: every request has the board's response timeout. A failed request is
// retried once: commands are safe to repeat because the robot acts only on a new
// sequence number. Before the retry, TCP closes and reconnects (a late reply must not
// pair with the next request); RTU flushes the line (and before every request) and
// reopens the device only when the device itself failed.
// A second failure throws RobotError; the next call tries to reconnect again, no
// sooner than 'reconnect_backoff' after the last attempt. Exception replies are not
// link failures and are thrown at once.

#include <cstdint>
#include <string>

#include "dentmark/firmware/board/board_config.h"
#include "dentmark/firmware/hal/robot/robot.h"

typedef struct _modbus modbus_t;

namespace dentmark::hal {

struct ModbusRobotCounters {
  long requests = 0;
  long timeouts = 0;
  long reconnects = 0;
  long exceptions = 0;
};

class ModbusRobot final : public Robot {
 public:
  // Does not connect yet (connect() does). Throws std::invalid_argument on a bad config.
  ModbusRobot(const board::ModbusConfig& config, clock::Clock& clock, double reconnect_backoff = 0.05);
  ~ModbusRobot() override;
  ModbusRobot(const ModbusRobot&) = delete;
  ModbusRobot& operator=(const ModbusRobot&) = delete;

  void connect() override;
  void disconnect() override;
  bool connected() const override { return connected_; }
  std::uint16_t move_to(const Transform& T_base_tool, double speed) override;
  std::uint16_t spray(double duration) override;
  std::uint16_t abort() override;
  std::uint16_t reset() override;
  void heartbeat() override;
  RobotStatus status() override;

  const ModbusRobotCounters& counters() const { return counters_; }
  std::string endpoint() const;

 private:
  std::uint16_t send_command(robot_link::Command command, const Transform* target, double speed,
                             std::uint16_t spray_ms);
  // Runs one request with the reconnect-and-retry policy; 'what' names it in errors.
  template <class Request>
  void with_retry(const char* what, Request request);
  void open_link();
  void close_link();

  board::ModbusConfig config_;
  clock::Clock& clock_;
  double backoff_;
  modbus_t* ctx_ = nullptr;
  bool connected_ = false;
  double last_attempt_ = -1e300;
  std::uint16_t sequence_ = 0;
  std::uint16_t heartbeat_ = 0;
  bool sequence_known_ = false;
  ModbusRobotCounters counters_;
};

}  // namespace dentmark::hal
