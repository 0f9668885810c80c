#include "dentmark/firmware/hal/robot/modbus_robot.h"

#include <modbus/modbus.h>

#include <cerrno>
#include <cmath>
#include <span>

namespace dentmark::hal {

namespace rl = robot_link;

namespace {

bool is_exception_reply(int err) {
  // Modbus exception codes 1..11 come back as MODBUS_ENOBASE + code.
  return err > MODBUS_ENOBASE && err <= MODBUS_ENOBASE + MODBUS_EXCEPTION_GATEWAY_TARGET;
}

void set_timeout(modbus_t* ctx, double seconds, int (*setter)(modbus_t*, uint32_t, uint32_t)) {
  const auto sec = static_cast<uint32_t>(seconds);
  const auto usec = static_cast<uint32_t>(std::lround((seconds - sec) * 1e6));
  setter(ctx, sec, std::min<uint32_t>(usec, 999999));
}

// Errors of the bytes on a serial line (no reply, bad CRC, wrong unit or function):
// the port itself is fine, so flushing and retrying is enough.
bool is_line_error(int err) {
  return err == ETIMEDOUT || err == EMBBADCRC || err == EMBBADDATA || err == EMBBADEXC || err == EMBUNKEXC ||
         err == EMBMDATA || err == EMBBADSLAVE;
}

}  // namespace

ModbusRobot::ModbusRobot(const board::ModbusConfig& config, clock::Clock& clock, double reconnect_backoff)
    : config_(config), clock_(clock), backoff_(reconnect_backoff) {
  if (!(config.timeout > 0.0)) throw std::invalid_argument("modbus robot: timeout must be > 0");
  if (config.transport == board::ModbusTransport::kTcp && (config.port < 1 || config.port > 65535))
    throw std::invalid_argument("modbus robot: port " + std::to_string(config.port) + " out of range");
}

ModbusRobot::~ModbusRobot() {
  close_link();
}

std::string ModbusRobot::endpoint() const {
  if (config_.transport == board::ModbusTransport::kTcp)
    return "modbus tcp " + config_.host + ":" + std::to_string(config_.port);
  return "modbus rtu " + config_.device;
}

void ModbusRobot::close_link() {
  if (ctx_) {
    modbus_close(ctx_);
    modbus_free(ctx_);
    ctx_ = nullptr;
  }
  connected_ = false;
}

void ModbusRobot::open_link() {
  close_link();
  last_attempt_ = clock_.now();
  if (config_.transport == board::ModbusTransport::kTcp) {
    ctx_ = modbus_new_tcp_pi(config_.host.c_str(), std::to_string(config_.port).c_str());
  } else {
    ctx_ = modbus_new_rtu(config_.device.c_str(), config_.baud, config_.parity, config_.data_bits,
                          config_.stop_bits);
  }
  if (!ctx_) throw RobotError(RobotError::Kind::kDisconnected, endpoint() + ": " + modbus_strerror(errno));
  modbus_set_slave(ctx_, config_.unit_id);
  set_timeout(ctx_, config_.timeout, modbus_set_response_timeout);
  // Gap allowed between bytes of one reply: a tenth of the request timeout.
  set_timeout(ctx_, config_.timeout / 10.0, modbus_set_byte_timeout);
  if (modbus_connect(ctx_) != 0) {
    const int err = errno;
    close_link();
    throw RobotError(RobotError::Kind::kDisconnected, endpoint() + ": connect: " + modbus_strerror(err));
  }
  connected_ = true;
  ++counters_.reconnects;
}

template <class Request>
void ModbusRobot::with_retry(const char* what, Request request) {
  const bool rtu = config_.transport == board::ModbusTransport::kRtu;
  for (int attempt = 0; attempt < 2; ++attempt) {
    if (!connected_) {
      // Back off between failed reconnects so a dead robot is not hammered; the
      // retry after a failure on a working link reconnects at once.
      if (attempt == 0 && clock_.now() - last_attempt_ < backoff_)
        throw RobotError(RobotError::Kind::kDisconnected,
                         endpoint() + ": " + what + ": link down, reconnect pending");
      open_link();
    }
    // A serial line keeps bytes of a late or garbled reply; drop them so they cannot
    // pair with this request.
    if (rtu) modbus_flush(ctx_);
    ++counters_.requests;
    errno = 0;
    if (request(ctx_) >= 0) return;
    const int err = errno;
    if (is_exception_reply(err)) {
      ++counters_.exceptions;
      throw RobotError(RobotError::Kind::kException,
                       endpoint() + ": " + what + ": exception reply: " + modbus_strerror(err));
    }
    if (err == ETIMEDOUT) ++counters_.timeouts;
    if (!rtu || !is_line_error(err)) {
      // TCP: a late answer could pair with the next request, so drop the connection
      // and start clean. RTU: the device itself failed (EIO, unplugged adapter): reopen.
      close_link();
    }
    if (attempt == 1)
      throw RobotError(err == ETIMEDOUT ? RobotError::Kind::kTimeout : RobotError::Kind::kDisconnected,
                       endpoint() + ": " + what + ": " + modbus_strerror(err));
  }
}

void ModbusRobot::connect() {
  if (connected_ && sequence_known_) return;
  if (!connected_) open_link();
  // Continue the robot's sequence and heartbeat so the first command is new to it.
  const RobotStatus s = status();
  sequence_ = s.sequence;
  heartbeat_ = s.heartbeat;
  sequence_known_ = true;
  heartbeat();
}

void ModbusRobot::disconnect() {
  close_link();
  sequence_known_ = false;
}

void ModbusRobot::heartbeat() {
  const std::uint16_t next = static_cast<std::uint16_t>(heartbeat_ + 1);
  with_retry("heartbeat",
             [&](modbus_t* ctx) { return modbus_write_register(ctx, rl::cmd::kHeartbeat, next); });
  heartbeat_ = next;
}

RobotStatus ModbusRobot::status() {
  std::uint16_t regs[rl::status::kCount] = {};
  with_retry("read status",
             [&](modbus_t* ctx) { return modbus_read_input_registers(ctx, 0, rl::status::kCount, regs); });
  const std::span<const std::uint16_t> r(regs);
  RobotStatus s;
  s.read_time = clock_.now();
  s.sequence = r[rl::status::kSequence];
  s.state = static_cast<rl::State>(r[rl::status::kState]);
  s.faults = r[rl::status::kFaults];
  s.heartbeat = r[rl::status::kHeartbeat];
  s.T_base_tool = rl::decode_pose(r.subspan(rl::status::kToolPose, 6));
  s.spray_count = rl::get_u32(r.subspan(rl::status::kSprayCount, 2), rl::kWordOrder);
  s.robot_time = rl::get_u32(r.subspan(rl::status::kRobotTimeMs, 2), rl::kWordOrder) * 1e-3;
  s.tool_speed = rl::get_f32(r.subspan(rl::status::kToolSpeed, 2), rl::kWordOrder);
  return s;
}

std::uint16_t ModbusRobot::send_command(rl::Command command, const Transform* target, double speed,
                                        std::uint16_t spray_ms) {
  if (!sequence_known_) connect();
  std::uint16_t regs[rl::cmd::kCount] = {};
  const std::uint16_t seq = static_cast<std::uint16_t>(sequence_ + 1);
  const std::uint16_t hb = static_cast<std::uint16_t>(heartbeat_ + 1);
  regs[rl::cmd::kCommand] = static_cast<std::uint16_t>(command);
  regs[rl::cmd::kSequence] = seq;
  regs[rl::cmd::kHeartbeat] = hb;
  regs[rl::cmd::kSprayMs] = spray_ms;
  int count = rl::cmd::kTarget;  // commands without a pose leave the target registers alone
  if (target) {
    rl::encode_pose(*target, std::span<std::uint16_t>(regs + rl::cmd::kTarget, 6));
    rl::put_f32(std::span<std::uint16_t>(regs + rl::cmd::kSpeed, 2), static_cast<float>(speed),
                rl::kWordOrder);
    count = rl::cmd::kCount;
  }
  // One write-multiple request: the robot sees the whole command or none of it.
  with_retry(rl::to_string(command),
             [&](modbus_t* ctx) { return modbus_write_registers(ctx, 0, count, regs); });
  sequence_ = seq;
  heartbeat_ = hb;
  return seq;
}

std::uint16_t ModbusRobot::move_to(const Transform& T_base_tool, double speed) {
  if (!(speed >= 0.0) || !std::isfinite(speed))
    throw std::invalid_argument("move_to: speed must be finite and >= 0");
  return send_command(rl::Command::kMove, &T_base_tool, speed, 0);
}

std::uint16_t ModbusRobot::spray(double duration) {
  const double ms = std::round(duration * 1e3);
  if (!(ms >= 1.0 && ms <= 65535.0))
    throw std::invalid_argument("spray: duration must be in [0.001, 65.535] s");
  return send_command(rl::Command::kSpray, nullptr, 0.0, static_cast<std::uint16_t>(ms));
}

std::uint16_t ModbusRobot::abort() {
  return send_command(rl::Command::kAbort, nullptr, 0.0, 0);
}

std::uint16_t ModbusRobot::reset() {
  return send_command(rl::Command::kIdle, nullptr, 0.0, 0);
}

}  // namespace dentmark::hal
