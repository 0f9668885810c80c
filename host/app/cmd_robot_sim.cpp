// `dentmark robot-sim`: the robot simulator as a Modbus TCP (or RTU) server
// (docs/robot-modbus.md). Thin: parse, run sim::robot::RobotSimulator, report.
#include <signal.h>

#include <cstdio>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "commands.h"
#include "dentmark/common/clock/clock.h"
#include "dentmark/common/log.h"
#include "dentmark/sim/robot/robot_record.h"
#include "dentmark/sim/robot/robot_simulator.h"

namespace dentmark::cli {
namespace {

struct RobotSimOptions {
  std::string host = "127.0.0.1";
  int port = 1502;
  std::string rtu_device;
  int baud = 115200;
  int unit_id = 1;
  double rate = 1.0;
  double duration = 0.0;
  std::vector<double> accuracy;  // x y z [rx ry rz]
  double repeatability = 0.0;
  double heartbeat_timeout = 0.5;
  double max_speed = 0.25;
  double max_acceleration = 1.0;
  std::string record;
};

// Waits for SIGINT/SIGTERM (blocked before the server thread starts, so only this
// thread takes them) or the end of 'duration' seconds of clock time.
int wait_for_stop(clock::Clock& clk, double duration) {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  const double end = duration > 0 ? clk.now() + duration : 0.0;
  for (;;) {
    timespec ts{0, 100'000'000};
    const int sig = sigtimedwait(&set, nullptr, &ts);
    if (sig > 0) return sig;
    if (duration > 0 && clk.now() >= end) return 0;
  }
}

int run(const RobotSimOptions& o) {
  sim::robot::RobotSimConfig cfg;
  cfg.heartbeat_timeout = o.heartbeat_timeout;
  cfg.repeatability = o.repeatability;
  cfg.max_speed = o.max_speed;
  cfg.max_acceleration = o.max_acceleration;
  cfg.unit_id = o.unit_id;
  if (!o.accuracy.empty()) {
    if (o.accuracy.size() != 3 && o.accuracy.size() != 6) {
      log::error("robot-sim: --accuracy takes 3 (x y z, m) or 6 (x y z m, rx ry rz rad) numbers");
      return 2;
    }
    Eigen::Vector3d t(o.accuracy[0], o.accuracy[1], o.accuracy[2]), r = Eigen::Vector3d::Zero();
    if (o.accuracy.size() == 6) r = Eigen::Vector3d(o.accuracy[3], o.accuracy[4], o.accuracy[5]);
    cfg.accuracy_error = make_transform_rotvec(r, t);
  }
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &set, nullptr);

  std::unique_ptr<clock::Clock> clk;
  if (o.rate == 1.0)
    clk = std::make_unique<clock::MonotonicClock>();
  else
    clk = std::make_unique<clock::SimClock>(o.rate);
  std::unique_ptr<sim::robot::RobotSimulator> robot;
  try {
    if (!o.rtu_device.empty()) {
      sim::robot::RtuEndpoint ep;
      ep.device = o.rtu_device;
      ep.baud = o.baud;
      robot = sim::robot::RobotSimulator::serve_rtu(cfg, *clk, ep);
      std::cout << "robot-sim serving modbus rtu on " << o.rtu_device << " unit " << o.unit_id << std::endl;
    } else {
      robot = sim::robot::RobotSimulator::serve_tcp(cfg, *clk, o.host, o.port);
      // Tools and tests read the port from this line (port 0 picks a free one).
      std::cout << "robot-sim listening on " << o.host << ":" << robot->port() << std::endl;
    }
  } catch (const std::exception& e) {
    log::error(e.what());
    return 2;
  }
  const int sig = wait_for_stop(*clk, o.duration);
  robot->stop();
  const auto traj = robot->trajectory();
  const auto sprays = robot->sprays();
  std::ostringstream os;
  os << "robot-sim stopped" << (sig ? " by signal " + std::to_string(sig) : std::string()) << ": "
     << robot->requests() << " requests, " << sprays.size() << " sprays, " << traj.size() << " tip samples";
  log::info(os.str());
  if (!o.record.empty()) {
    try {
      sim::robot::write_robot_record(o.record, traj, sprays);
    } catch (const std::exception& e) {
      log::error(e.what());
      return 2;
    }
  }
  return 0;
}

}  // namespace

void register_robot_sim(CLI::App& app) {
  auto o = std::make_shared<RobotSimOptions>();
  CLI::App* cmd =
      app.add_subcommand("robot-sim", "Robot simulator: a Modbus server speaking docs/robot-modbus.md");
  cmd->add_option("--host", o->host, "Address to listen on")->capture_default_str();
  cmd->add_option("--port", o->port, "TCP port; 0 picks a free port and prints it")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
  cmd->add_option("--rtu", o->rtu_device, "Serve Modbus RTU on this serial device instead of TCP");
  cmd->add_option("--baud", o->baud, "RTU baud rate")->capture_default_str();
  cmd->add_option("--unit", o->unit_id, "RTU unit id")->check(CLI::Range(1, 247))->capture_default_str();
  cmd->add_option("--rate", o->rate, "Simulated seconds per real second")
      ->check(CLI::Range(1e-3, 1e3))
      ->capture_default_str();
  cmd->add_option("--duration", o->duration,
                  "Stop after this many simulated seconds (0: until SIGINT/SIGTERM)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--accuracy", o->accuracy, "Absolute accuracy error: x y z (m) [rx ry rz (rad)]")
      ->expected(3, 6);
  cmd->add_option("--repeatability", o->repeatability, "Repeatability sigma per move (m)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--heartbeat-timeout", o->heartbeat_timeout, "Heartbeat watchdog (s)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--max-speed", o->max_speed, "Tool speed limit (m/s)")->check(CLI::PositiveNumber);
  cmd->add_option("--max-acceleration", o->max_acceleration, "Tool acceleration limit (m/s^2)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--record", o->record, "Write the tip trajectory and sprays as JSON here on exit");
  cmd->callback([o] { exit_code() = run(*o); });
}

}  // namespace dentmark::cli
