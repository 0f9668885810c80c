#pragma once
// The edge daemon's wiring: the one place where a board file, a calibration folder and
// a state folder become a running station (design.md §4–5). `dentmark-edge run` uses
// it with the board's real drivers; `dentmark-edge simulate` uses it unchanged with a
// simulation board (simulated GPIO and cameras, the robot simulator over Modbus TCP):
// the twin is this daemon, only its drivers are simulated.
//
// Start order, each step with a clear error when it fails:
//   calibration → GPIO (valve first, closed) → safety supervisor → robot → cameras →
//   state directory → station (interrupted jobs ended) → link listener.
// stop() runs the reverse order; the valve is closed on every path (the supervisor's
// destructor and process guards).

#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "dentmark/common/clock/clock.h"
#include "dentmark/common/protocol/hmac_key.h"
#include "dentmark/firmware/board/board_config.h"
#include "dentmark/firmware/hal/board_hal.h"
#include "dentmark/firmware/hal/safety/safety_supervisor.h"
#include "dentmark/firmware/link/link_server.h"
#include "dentmark/firmware/station/camera_tracking.h"
#include "dentmark/firmware/station/job_store.h"
#include "dentmark/firmware/station/station.h"
#include "dentmark/firmware/station/station_calibration.h"
#include "dentmark/firmware/station/supervised_safety.h"

namespace dentmark::daemon {

class DaemonError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct DaemonOptions {
  board::BoardConfig board;
  std::filesystem::path calibration_dir;
  std::filesystem::path state_dir;
  std::string key_file;  // empty: unauthenticated link
  int port = -1;         // -1: the board's link.port; 0: any free port
  std::string bind_address = "0.0.0.0";
  double replay_window = 30.0;
  int max_clients = 8;
  hal::HalChoice hal;                      // simulated cameras need hal.render
  station::StationConfig station;          // planner chain and limits are filled from calibration and board
  station::CameraTrackingConfig tracking;  // calibration and models are filled from the folder
  double watchdog_timeout = 0.2;           // s: valve forced off when the control loop stalls
  std::function<double()> unix_time;       // default: the system clock
  // Replaces the cameras' tracking (diagnostics: the twin's true motion). Empty: the
  // board's cameras and the tracker.
  std::function<std::unique_ptr<station::PanelTracking>(const station::StationCalibration&)>
      tracking_override;
  // Called on the link thread before each accepted request is handled (the twin runs
  // its clock by it). Empty on the edge box.
  std::function<void(const protocol::Decoded&)> before_request;
  // Called on the link thread after each accepted request was handled. Empty on the box.
  std::function<void(const protocol::Decoded&)> after_request;
};

class EdgeDaemon {
 public:
  // Opens every device (throws DaemonError naming what failed and why).
  EdgeDaemon(DaemonOptions options, clock::Clock& clock);
  ~EdgeDaemon();
  EdgeDaemon(const EdgeDaemon&) = delete;
  EdgeDaemon& operator=(const EdgeDaemon&) = delete;

  // Ends interrupted jobs, starts the job thread, the cameras and the listener.
  void start();
  void stop();  // idempotent

  std::uint16_t port() const { return server_ ? server_->port() : 0; }
  station::Station& station() { return *station_; }
  station::CameraTracking* cameras() { return cameras_; }  // null with a tracking override
  const std::filesystem::path& state_dir() const { return options_.state_dir; }
  // One line for logs and sd_notify STATUS=.
  std::string describe() const;

 private:
  DaemonOptions options_;
  clock::Clock& clock_;
  station::StationCalibration calibration_;
  std::optional<protocol::HmacKey> key_;
  std::shared_ptr<hal::Gpio> gpio_;
  std::unique_ptr<hal::InputLine> part_present_;
  std::unique_ptr<hal::SafetySupervisor> supervisor_;
  std::unique_ptr<station::SupervisedSafety> safety_io_;
  std::unique_ptr<hal::Robot> robot_;
  std::unique_ptr<hal::Camera> camera_left_, camera_right_;
  std::unique_ptr<station::PanelTracking> tracking_;
  station::CameraTracking* cameras_ = nullptr;  // tracking_ when it is the cameras'
  std::unique_ptr<station::JobStore> store_;
  std::unique_ptr<station::Station> station_;
  std::unique_ptr<link::LinkServer> server_;
  bool started_ = false;
};

}  // namespace dentmark::daemon
