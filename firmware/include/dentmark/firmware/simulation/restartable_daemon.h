#pragma once
// The twin's edge daemon, which a fault can kill and systemd bring back
// (docs/station-sim.md, "Faults"). The twin shares one process with its daemon, so
// kill() does to the world what SIGKILL does to it:
//   - the daemon's GPIO requests end: the valve line falls back to inactive (closed);
//   - the robot hears nothing more from it: its heartbeat stops, and the robot's own
//     watchdog stops the motion;
//   - its link sockets close: the host sees the connection drop;
//   - its state directory keeps what was on disk at the kill.
// Nothing the killed daemon's code does afterwards (its threads end, its stop path
// runs) reaches any of them. restart() then starts a new daemon on the same options,
// port and state directory, as `Restart=always` does on the box.

#include <atomic>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/daemon/edge_daemon.h"
#include "dentmark/firmware/hal/gpio/sim_gpio.h"
#include "dentmark/sim/robot/robot_simulator.h"

namespace dentmark::simulation {

class RestartableDaemon {
 public:
  // make_options(n): the options of the n-th daemon of the run (n = 0, 1, ...). Each
  // must use 'chip' as its simulated GPIO (HalChoice::sim_chip) and 'robot' as its robot.
  // on_restart: called once a restarted daemon runs.
  RestartableDaemon(std::function<daemon::DaemonOptions(int)> make_options, clock::Clock& clock,
                    hal::SimGpio& chip, sim::robot::RobotSimulator& robot, std::function<void()> on_restart);
  ~RestartableDaemon();
  RestartableDaemon(const RestartableDaemon&) = delete;
  RestartableDaemon& operator=(const RestartableDaemon&) = delete;

  // The daemon now running; empty between a kill and its restart.
  std::shared_ptr<daemon::EdgeDaemon> current() const;
  // Whether daemon n is the one running (its callbacks act only while it is).
  bool is_current(int n) const { return generation_.load() == n; }
  std::uint16_t port() const { return port_.load(); }
  // Frame pairs the cameras captured, over every daemon of the run.
  long pairs_captured() const;

  // SIGKILL, as the devices, the robot, the host and the disk see it (above).
  void kill();
  // A new daemon on the same options, port and state directory, 'after' seconds after
  // the kill (systemd's RestartSec).
  void restart(double after);
  void stop();

 private:
  void start_daemon();

  std::function<daemon::DaemonOptions(int)> make_options_;
  std::function<void()> on_restart_;
  clock::Clock& clock_;
  hal::SimGpio& chip_;
  sim::robot::RobotSimulator& robot_;
  mutable std::mutex mutex_;
  std::shared_ptr<daemon::EdgeDaemon> daemon_;
  std::atomic<int> generation_{0};
  std::atomic<std::uint16_t> port_{0};
  long pairs_before_ = 0;  // captured by daemons killed before this one
  double killed_at_ = 0.0;
};

}  // namespace dentmark::simulation
