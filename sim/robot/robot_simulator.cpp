#include "dentmark/sim/robot/robot_simulator.h"

#include <arpa/inet.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>

namespace dentmark::sim::robot {

namespace rl = robot_link;

struct RobotSimulator::Endpoint {
  modbus_t* ctx = nullptr;
  modbus_mapping_t* map = nullptr;
  int listen_fd = -1;  // TCP
  int serial_fd = -1;  // RTU
  std::vector<int> clients;
  bool rtu = false;

  ~Endpoint() {
    for (int fd : clients) ::close(fd);
    if (listen_fd >= 0) ::close(listen_fd);
    if (rtu && ctx) modbus_close(ctx);
    if (map) modbus_mapping_free(map);
    if (ctx) modbus_free(ctx);
  }
};

namespace {

// Bounded so a runaway recording cannot exhaust memory on a long simulation.
constexpr std::size_t kMaxSamples = 2'000'000;

bool is_write(int function) {
  return function == 0x06 || function == 0x10 || function == 0x17;
}

modbus_mapping_t* new_mapping() {
  modbus_mapping_t* map =
      modbus_mapping_new_start_address(0, 0, 0, 0, 0, rl::cmd::kCount, 0, rl::status::kCount);
  if (!map) throw std::runtime_error(std::string("robot sim: modbus_mapping_new: ") + modbus_strerror(errno));
  return map;
}

}  // namespace

RobotSimulator::RobotSimulator(const RobotSimConfig& config, clock::Clock& clock)
    : config_(config), clock_(clock), rng_(config.seed), nominal_(config.home) {
  if (!(config.max_speed > 0) || !(config.max_acceleration > 0) || !(config.max_angular_speed > 0) ||
      !(config.max_angular_acceleration > 0) || !(config.heartbeat_timeout > 0) || !(config.step > 0) ||
      !(config.repeatability >= 0))
    throw std::invalid_argument("robot sim: speeds, accelerations, timeout and step must be > 0");
  if (!is_rigid(config.accuracy_error, 1e-6))
    throw std::invalid_argument("robot sim: accuracy_error is not rigid");
  // The status block reports poses in signed 16-bit 0.1 mm units.
  const double reach = 32767.0 / rl::kPositionScale;
  if ((config.workspace_min.array() < -reach).any() || (config.workspace_max.array() > reach).any() ||
      (config.home.translation().array().abs() > reach).any())
    throw std::invalid_argument("robot sim: workspace and home must lie within +-3.2767 m (register range)");
}

std::unique_ptr<RobotSimulator> RobotSimulator::serve_tcp(const RobotSimConfig& config, clock::Clock& clock,
                                                          const std::string& host, int port) {
  if (port < 0 || port > 65535) throw std::invalid_argument("robot sim: port " + std::to_string(port));
  std::unique_ptr<RobotSimulator> sim(new RobotSimulator(config, clock));
  auto ep = std::make_unique<Endpoint>();
  ep->ctx = modbus_new_tcp(host.c_str(), port);
  if (!ep->ctx)
    throw std::runtime_error("robot sim: modbus_new_tcp(" + host + "): " + modbus_strerror(errno));
  ep->map = new_mapping();
  ep->listen_fd = modbus_tcp_listen(ep->ctx, 8);
  if (ep->listen_fd < 0)
    throw std::runtime_error("robot sim: cannot listen on " + host + ":" + std::to_string(port) + ": " +
                             modbus_strerror(errno));
  sockaddr_in addr{};
  socklen_t len = sizeof addr;
  if (::getsockname(ep->listen_fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0)
    throw std::runtime_error(std::string("robot sim: getsockname: ") + std::strerror(errno));
  sim->port_ = ntohs(addr.sin_port);
  sim->start(std::move(ep));
  return sim;
}

std::unique_ptr<RobotSimulator> RobotSimulator::serve_rtu(const RobotSimConfig& config, clock::Clock& clock,
                                                          const RtuEndpoint& e) {
  std::unique_ptr<RobotSimulator> sim(new RobotSimulator(config, clock));
  auto ep = std::make_unique<Endpoint>();
  ep->rtu = true;
  ep->ctx = modbus_new_rtu(e.device.c_str(), e.baud, e.parity, e.data_bits, e.stop_bits);
  if (!ep->ctx)
    throw std::runtime_error("robot sim: modbus_new_rtu(" + e.device + "): " + modbus_strerror(errno));
  ep->map = new_mapping();
  modbus_set_slave(ep->ctx, config.unit_id);
  if (modbus_connect(ep->ctx) != 0)
    throw std::runtime_error("robot sim: cannot open " + e.device + ": " + modbus_strerror(errno));
  ep->serial_fd = modbus_get_socket(ep->ctx);
  sim->start(std::move(ep));
  return sim;
}

void RobotSimulator::start(std::unique_ptr<Endpoint> endpoint) {
  endpoint_ = std::move(endpoint);
  const double now = clock_.now();
  publish_status(now);
  record(now, true);
  thread_ = std::thread([this] { serve(); });
}

RobotSimulator::~RobotSimulator() {
  stop();
}

void RobotSimulator::stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

void RobotSimulator::inject_drop(int n) {
  std::lock_guard<std::mutex> lock(mutex_);
  drop_n_ = n;
}

void RobotSimulator::inject_delay(double real_seconds, int n) {
  std::lock_guard<std::mutex> lock(mutex_);
  delay_s_ = real_seconds;
  delay_n_ = n;
}

void RobotSimulator::inject_exception(int exception_code, int n) {
  std::lock_guard<std::mutex> lock(mutex_);
  exception_code_ = exception_code;
  exception_n_ = n;
}

void RobotSimulator::inject_drive_fault() {
  std::lock_guard<std::mutex> lock(mutex_);
  const double now = clock_.now();
  step(now);
  stop_motion(now, rl::fault::kDrive, rl::State::kStopped);
  publish_status(now);
}

void RobotSimulator::clear_fault() {
  std::lock_guard<std::mutex> lock(mutex_);
  const double now = clock_.now();
  step(now);
  if (state_ == rl::State::kStopped || state_ == rl::State::kFault) state_ = rl::State::kIdle;
  faults_ = 0;
  publish_status(now);
}

std::vector<TipSample> RobotSimulator::trajectory() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return trajectory_;
}

std::vector<SprayRecord> RobotSimulator::sprays() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return sprays_;
}

// The readers step the robot to the clock's now first: what they see does not depend
// on when the serve loop last woke.
Transform RobotSimulator::nominal_pose() {
  std::lock_guard<std::mutex> lock(mutex_);
  step(clock_.now());
  return nominal_;
}

Transform RobotSimulator::true_pose() {
  std::lock_guard<std::mutex> lock(mutex_);
  step(clock_.now());
  return true_from_nominal(nominal_, noise_);
}

rl::State RobotSimulator::state() {
  std::lock_guard<std::mutex> lock(mutex_);
  step(clock_.now());
  return state_;
}

std::uint16_t RobotSimulator::faults() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return faults_;
}

Transform RobotSimulator::true_from_nominal(const Transform& nominal, const Eigen::Vector3d& noise) const {
  Transform t = config_.accuracy_error * nominal;
  t.translation() += noise;
  return t;
}

void RobotSimulator::serve() {
  Endpoint& ep = *endpoint_;
  std::vector<std::uint8_t> query(MODBUS_MAX_ADU_LENGTH);
  while (!stop_) {
    std::vector<pollfd> fds;
    if (ep.rtu) {
      fds.push_back({ep.serial_fd, POLLIN, 0});
    } else {
      fds.push_back({ep.listen_fd, POLLIN, 0});
      for (int fd : ep.clients) fds.push_back({fd, POLLIN, 0});
    }
    // Wake at the motion step (in real time at the clock's rate), within [0.5, 10] ms.
    const double wait = std::clamp(clock_.to_real(config_.step), 0.0005, 0.010);
    const int r = ::poll(fds.data(), fds.size(), static_cast<int>(std::ceil(wait * 1000.0)));
    {
      std::lock_guard<std::mutex> lock(mutex_);
      step(clock_.now());
    }
    if (r <= 0) continue;  // timeout, or EINTR: step again
    for (const pollfd& p : fds) {
      if (!(p.revents & (POLLIN | POLLHUP | POLLERR))) continue;
      if (!ep.rtu && p.fd == ep.listen_fd) {
        int server = ep.listen_fd;
        const int fd = modbus_tcp_accept(ep.ctx, &server);
        if (fd >= 0) {
          ep.clients.push_back(fd);
          ++connections_;
        }
        continue;
      }
      modbus_set_socket(ep.ctx, p.fd);
      const int n = modbus_receive(ep.ctx, query.data());
      if (n < 0) {
        if (ep.rtu) {
          modbus_flush(ep.ctx);  // garbled frame (CRC, length): resynchronise on the next one
        } else {
          ::close(p.fd);  // peer closed or sent garbage: forget the connection
          std::erase(ep.clients, p.fd);
        }
        continue;
      }
      if (n == 0) continue;  // addressed to another unit
      ++requests_;
      serve_request(p.fd, query.data(), n);
    }
  }
}

void RobotSimulator::serve_request(int fd, const std::uint8_t* query, int length) {
  Endpoint& ep = *endpoint_;
  double delay = 0.0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (drop_n_ > 0) {
      --drop_n_;
      if (!ep.rtu) {
        ::close(fd);
        std::erase(ep.clients, fd);
      }
      return;
    }
    if (exception_n_ > 0) {
      --exception_n_;
      modbus_reply_exception(ep.ctx, query, static_cast<unsigned>(exception_code_));
      return;
    }
    if (delay_n_ > 0) {
      --delay_n_;
      delay = delay_s_;
    }
  }
  if (delay > 0.0) std::this_thread::sleep_for(std::chrono::duration<double>(delay));
  const int function = query[modbus_get_header_length(ep.ctx)];
  // The request's time: the client waits for the reply, so on a lock-step clock time
  // stands still until then, but not after; the command takes effect at this time too.
  double now = 0.0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    now = clock_.now();
    step(now);
    publish_status(now);
  }
  if (modbus_reply(ep.ctx, query, length, ep.map) < 0 && !ep.rtu) {
    ::close(fd);
    std::erase(ep.clients, fd);
    return;
  }
  if (is_write(function)) {
    std::lock_guard<std::mutex> lock(mutex_);
    on_command_block(now);
  }
}

// Called with mutex_ held after a write to the command block.
void RobotSimulator::on_command_block(double now) {
  const std::uint16_t* regs = endpoint_->map->tab_registers;
  if (regs[rl::cmd::kHeartbeat] != heartbeat_) {
    heartbeat_ = regs[rl::cmd::kHeartbeat];
    heartbeat_time_ = now;
  }
  const std::uint16_t seq = regs[rl::cmd::kSequence];
  if (seq == sequence_) {
    publish_status(now);
    return;
  }
  sequence_ = seq;
  const auto reject = [&](std::uint16_t bits) {
    state_ = rl::State::kFault;
    faults_ = bits;
    publish_status(now);
  };
  if (now - heartbeat_time_ > config_.heartbeat_timeout) return reject(rl::fault::kHeartbeatLost);
  faults_ = 0;
  const auto command = static_cast<rl::Command>(regs[rl::cmd::kCommand]);
  switch (command) {
    case rl::Command::kIdle:
      state_ = rl::State::kIdle;
      break;
    case rl::Command::kAbort:
      stop_motion(now, rl::fault::kAborted, rl::State::kStopped);
      break;
    case rl::Command::kSpray: {
      if (stopping_) return reject(rl::fault::kBadCommand);
      const double duration = regs[rl::cmd::kSprayMs] * 1e-3;
      if (duration <= 0.0) return reject(rl::fault::kBadCommand);
      if (state_ == rl::State::kMoving) return reject(rl::fault::kBadCommand);
      state_ = rl::State::kSpraying;
      spray_end_ = now + duration;
      ++spray_count_;
      sprays_.push_back({now, seq, duration, true_from_nominal(nominal_, noise_), nominal_});
      break;
    }
    case rl::Command::kMove: {
      if (stopping_) return reject(rl::fault::kBadCommand);  // still braking from the last stop
      const Transform target = rl::decode_pose(std::span<const std::uint16_t>(regs + rl::cmd::kTarget, 6));
      const float speed_reg =
          rl::get_f32(std::span<const std::uint16_t>(regs + rl::cmd::kSpeed, 2), rl::kWordOrder);
      if (!std::isfinite(speed_reg) || speed_reg < 0.0f) return reject(rl::fault::kBadCommand);
      const Eigen::Vector3d p = target.translation();
      if ((p.array() < config_.workspace_min.array()).any() ||
          (p.array() > config_.workspace_max.array()).any())
        return reject(rl::fault::kWorkspace);
      const double v_lin =
          speed_reg > 0.0f ? std::min<double>(speed_reg, config_.max_speed) : config_.max_speed;
      move_from_ = nominal_;
      move_to_ = target;
      noise_from_ = noise_;
      std::normal_distribution<double> gauss(0.0, config_.repeatability);
      noise_to_ = config_.repeatability > 0 ? Eigen::Vector3d(gauss(rng_), gauss(rng_), gauss(rng_))
                                            : Eigen::Vector3d::Zero();
      path_length_ = (target.translation() - nominal_.translation()).norm();
      const double angle = rotation_angle_between(nominal_, target);
      // One profile over u in [0, 1] that respects both the linear and the angular limits.
      double v = 1e9, a = 1e9;
      if (path_length_ > 0) {
        v = std::min(v, v_lin / path_length_);
        a = std::min(a, config_.max_acceleration / path_length_);
      }
      if (angle > 0) {
        v = std::min(v, config_.max_angular_speed / angle);
        a = std::min(a, config_.max_angular_acceleration / angle);
      }
      profile_ = TrapezoidProfile(1.0, v, a);
      accel_ = a;
      move_start_ = now;
      state_ = rl::State::kMoving;
      record(now, true);
      break;
    }
    default:
      return reject(rl::fault::kBadCommand);
  }
  step(now);
  publish_status(now);
}

void RobotSimulator::move_along_path(double u) {
  nominal_.translation() = move_from_.translation() + u * (move_to_.translation() - move_from_.translation());
  const Eigen::Quaterniond q0(move_from_.linear()), q1(move_to_.linear());
  nominal_.linear() = q0.slerp(u, q1).toRotationMatrix();
  noise_ = noise_from_ + u * (noise_to_ - noise_from_);
}

// Advances motion, spray and the heartbeat watchdog to 'now' (mutex_ held).
void RobotSimulator::step(double now) {
  if (stopping_) {
    // Braking along the path at the move's acceleration: speed and acceleration stay bounded.
    const double t_stop = stop_v0_ / accel_;
    const double dt = std::min(now - stop_start_, t_stop);
    move_along_path(stop_u0_ + stop_v0_ * dt - 0.5 * accel_ * dt * dt);
    speed_ = (stop_v0_ - accel_ * dt) * path_length_;
    if (now - stop_start_ >= t_stop) {
      speed_ = 0.0;
      stopping_ = false;
      record(stop_start_ + t_stop, true);  // when it came to rest, whenever this step runs
    } else {
      record(now, false);
    }
    return;
  }
  const double watchdog_fires = heartbeat_time_ + config_.heartbeat_timeout;
  if ((state_ == rl::State::kMoving || state_ == rl::State::kSpraying) && now > watchdog_fires) {
    // The robot program's watchdog: the edge stopped talking, so stop and close the
    // sprayer, from the instant the watchdog fired (not when this step happens to run).
    stop_motion(watchdog_fires, rl::fault::kHeartbeatLost, rl::State::kStopped);
    if (stopping_) step(now);
    return;
  }
  if (state_ == rl::State::kMoving) {
    const double t = now - move_start_;
    move_along_path(profile_.position(t));
    speed_ = profile_.speed(t) * path_length_;
    if (t >= profile_.duration()) {
      nominal_ = move_to_;
      noise_ = noise_to_;
      speed_ = 0.0;
      state_ = rl::State::kIdle;
      record(move_start_ + profile_.duration(), true);
    } else {
      record(now, false);
    }
  } else if (state_ == rl::State::kSpraying && now >= spray_end_) {
    state_ = rl::State::kIdle;
  }
}

void RobotSimulator::stop_motion(double now, std::uint16_t fault_bits, rl::State state) {
  // The sprayer closes and the state changes at once; a moving tool brakes along its
  // path at the move's acceleration (step() carries that out).
  if (stopping_) step(now);  // already braking (a second stop): bring the speed up to date
  if (state_ == rl::State::kMoving) {
    const double t = now - move_start_;
    stop_u0_ = profile_.position(t);
    stop_v0_ = profile_.speed(t);
    stop_start_ = now;
    stopping_ = stop_v0_ > 0.0;
    move_along_path(stop_u0_);
  }
  if (!stopping_) speed_ = 0.0;
  state_ = state;
  faults_ = static_cast<std::uint16_t>(faults_ | fault_bits);
  spray_end_ = now;
  record(now, true);
}

void RobotSimulator::record(double now, bool force) {
  if (!force && now - last_record_ < config_.record_period) return;
  if (trajectory_.size() >= kMaxSamples) return;
  last_record_ = now;
  trajectory_.push_back({now, true_from_nominal(nominal_, noise_), nominal_, speed_});
}

void RobotSimulator::publish_status(double now) {
  if (!endpoint_) return;
  std::uint16_t* in = endpoint_->map->tab_input_registers;
  in[rl::status::kSequence] = sequence_;
  in[rl::status::kState] = static_cast<std::uint16_t>(state_);
  in[rl::status::kFaults] = faults_;
  in[rl::status::kHeartbeat] = heartbeat_;
  rl::encode_pose(nominal_, std::span<std::uint16_t>(in + rl::status::kToolPose, 6));
  rl::put_u32(std::span<std::uint16_t>(in + rl::status::kSprayCount, 2), spray_count_, rl::kWordOrder);
  const auto ms = static_cast<std::uint64_t>(std::max(0.0, now) * 1000.0);
  rl::put_u32(std::span<std::uint16_t>(in + rl::status::kRobotTimeMs, 2), static_cast<std::uint32_t>(ms),
              rl::kWordOrder);
  rl::put_f32(std::span<std::uint16_t>(in + rl::status::kToolSpeed, 2), static_cast<float>(speed_),
              rl::kWordOrder);
}

}  // namespace dentmark::sim::robot
