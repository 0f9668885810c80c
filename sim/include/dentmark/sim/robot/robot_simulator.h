#pragma once
// The robot's twin (design.md §7): a real Modbus server (libmodbus, TCP or RTU) that
// speaks docs/robot-modbus.md. It moves the tool in straight Cartesian lines at
// bounded speed and acceleration, with a configurable absolute accuracy error and
// repeatability noise, enforces workspace limits and the heartbeat watchdog, can
// inject communication faults, and records where the tip really was over time and
// at each spray.
//
// One thread serves the bus and steps the motion; every time comes from the injected
// clock, so with a fast SimClock the robot runs faster than real time.

#include <Eigen/Core>
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <numbers>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "dentmark/common/clock/clock.h"
#include "dentmark/common/geometry/transform.h"
#include "dentmark/common/robot_link/register_map.h"
#include "dentmark/sim/robot/trapezoid_profile.h"

namespace dentmark::sim::robot {

struct RobotSimConfig {
  Eigen::Vector3d workspace_min{-0.60, -0.80, -0.10};  // m, in base
  Eigen::Vector3d workspace_max{0.90, 0.80, 1.20};     // m, in base
  double max_speed = 0.25;                             // m/s, tool tip
  double max_acceleration = 1.0;                       // m/s²
  double max_angular_speed = 1.0;                      // rad/s
  double max_angular_acceleration = 4.0;               // rad/s²
  // Absolute accuracy: where the tip really is, T_true_nominal, relative to where the
  // robot's kinematic model (and so its status block) says it is.
  Transform accuracy_error = Transform::Identity();
  // Repeatability: σ (m) of an isotropic Gaussian offset drawn anew for every move.
  double repeatability = 0.0;
  double heartbeat_timeout = 0.5;  // s without a heartbeat change before motion stops
  double record_period = 0.01;     // s between recorded tip samples while moving
  double step = 0.001;             // s, motion update period
  Transform home =
      make_transform_rotvec(Eigen::Vector3d(std::numbers::pi, 0, 0), Eigen::Vector3d(0.4, 0.0, 0.5));
  std::uint32_t seed = 1;
  int unit_id = 1;  // RTU slave address
};

struct TipSample {
  double time = 0.0;                              // s, simulator clock
  Transform T_base_tip = Transform::Identity();   // where the tip really is
  Transform T_base_tool = Transform::Identity();  // where the robot reports it (nominal)
  double speed = 0.0;                             // m/s, nominal
};

struct SprayRecord {
  double time = 0.0;  // s, when the sprayer opened
  std::uint16_t sequence = 0;
  double duration = 0.0;                          // s
  Transform T_base_tip = Transform::Identity();   // true tip pose
  Transform T_base_tool = Transform::Identity();  // nominal pose
};

struct RtuEndpoint {
  std::string device;
  int baud = 115200;
  char parity = 'N';
  int data_bits = 8;
  int stop_bits = 1;
};

class RobotSimulator {
 public:
  // Listens on host:port; port 0 picks a free port (see port()). Throws
  // std::runtime_error when the socket cannot be opened.
  static std::unique_ptr<RobotSimulator> serve_tcp(const RobotSimConfig& config, clock::Clock& clock,
                                                   const std::string& host = "127.0.0.1", int port = 0);
  // Serves Modbus RTU on a serial device (or one end of a pty pair).
  static std::unique_ptr<RobotSimulator> serve_rtu(const RobotSimConfig& config, clock::Clock& clock,
                                                   const RtuEndpoint& endpoint);
  ~RobotSimulator();
  RobotSimulator(const RobotSimulator&) = delete;
  RobotSimulator& operator=(const RobotSimulator&) = delete;

  int port() const { return port_; }  // TCP port actually bound (0 for RTU)
  void stop();                        // stops serving; idempotent

  // Fault injection, each for the next n requests that reach the server.
  void inject_drop(int n);                           // close the connection instead of replying
  void inject_delay(double real_seconds, int n);     // reply late (real time: client timeouts are real)
  void inject_exception(int exception_code, int n);  // Modbus exception reply (e.g. 4 = server failure)
  // The robot's own fault now (a drive fault): it brakes, closes the sprayer and reports
  // state stopped with fault::kDrive until a reset.
  void inject_drive_fault();
  // The robot's operator clears its own fault at the robot (the pendant's reset, which
  // the station never sends for a drive fault): state idle, no fault bits.
  void clear_fault();

  // Observation (thread-safe snapshots).
  std::vector<TipSample> trajectory() const;
  std::vector<SprayRecord> sprays() const;
  Transform nominal_pose();
  Transform true_pose();
  robot_link::State state();
  std::uint16_t faults() const;
  long requests() const { return requests_.load(); }
  long connections() const { return connections_.load(); }

 private:
  struct Endpoint;
  RobotSimulator(const RobotSimConfig& config, clock::Clock& clock);
  void start(std::unique_ptr<Endpoint> endpoint);
  void serve();
  void serve_request(int fd, const std::uint8_t* query, int length);
  void on_command_block(double now);
  void step(double now);
  void stop_motion(double now, std::uint16_t fault_bits, robot_link::State state);
  void move_along_path(double u);
  void record(double now, bool force);
  void publish_status(double now);
  Transform true_from_nominal(const Transform& nominal, const Eigen::Vector3d& noise) const;

  RobotSimConfig config_;
  clock::Clock& clock_;
  std::unique_ptr<Endpoint> endpoint_;
  int port_ = 0;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<long> requests_{0};
  std::atomic<long> connections_{0};
  std::mt19937 rng_;

  mutable std::mutex mutex_;  // guards everything below
  int drop_n_ = 0;
  int delay_n_ = 0;
  double delay_s_ = 0.0;
  int exception_n_ = 0;
  int exception_code_ = 0;

  // Motion state.
  robot_link::State state_ = robot_link::State::kIdle;
  std::uint16_t faults_ = 0;
  std::uint16_t sequence_ = 0;  // last command taken (power-up: 0, as the holding register)
  std::uint16_t heartbeat_ = 0;
  double heartbeat_time_ = -1e300;  // when the heartbeat register last changed
  std::uint32_t spray_count_ = 0;
  Transform nominal_;
  Eigen::Vector3d noise_ = Eigen::Vector3d::Zero();
  Transform move_from_, move_to_;
  Eigen::Vector3d noise_from_ = Eigen::Vector3d::Zero(), noise_to_ = Eigen::Vector3d::Zero();
  TrapezoidProfile profile_;  // over the normalised path parameter u in [0, 1]
  double accel_ = 1.0;        // profile_'s acceleration, in u/s²
  bool stopping_ = false;     // decelerating along the path after abort / heartbeat loss
  double stop_start_ = 0.0, stop_u0_ = 0.0, stop_v0_ = 0.0;
  double path_length_ = 0.0;  // m
  double move_start_ = 0.0;
  double spray_end_ = 0.0;
  double speed_ = 0.0;
  double last_record_ = -1e300;
  std::vector<TipSample> trajectory_;
  std::vector<SprayRecord> sprays_;
};

}  // namespace dentmark::sim::robot
