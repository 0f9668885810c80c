// `dentmark-edge run`: the edge daemon (design.md §4). Parses its options, wires the
// station through daemon::EdgeDaemon and serves until SIGINT or SIGTERM, telling
// systemd its state (Type=notify: READY=1, WATCHDOG=1, STATUS=, STOPPING=1).
#include <systemd/sd-daemon.h>

#include <chrono>
#include <memory>
#include <string>

#include "commands.h"
#include "daemon_paths.h"
#include "dentmark/common/log.h"
#include "dentmark/common/protocol/hmac_key.h"
#include "dentmark/common/version.h"
#include "dentmark/firmware/daemon/edge_daemon.h"
#include "stop_signal.h"

namespace dentmark::edge {
namespace {

struct RunOptions {
  std::string board_file;
  std::string calibration_dir;  // default: /etc/dentmark/calibration
  std::string state_dir;        // default: $STATE_DIRECTORY (systemd) or /var/lib/dentmark
  bool check_only = false;
  bool verbose = false;
  int port = -1;  // -1: the board's link.port; 0: any free port
  std::string bind_address = "0.0.0.0";
  std::string key_file;
  double replay_window = 30.0;
  int max_clients = 8;
  double watchdog_timeout = 0.2;  // s without a control-loop kick before the valve is forced off
  double tracking_timeout = station::JobConfig{}.tracking_timeout;
  double max_estimate_age = station::JobConfig{}.max_estimate_age;
  double camera_timeout = station::CameraTrackingConfig{}.grab_timeout;
};

std::string status_line(const protocol::Status& s) {
  std::string line = std::string(protocol::to_string(s.state));
  if (s.job_id != 0)
    line += ", job " + std::to_string(s.job_id) + " (" + std::to_string(s.defects_reported) + "/" +
            std::to_string(s.defects_total) + " reported)";
  if (s.fault_bits != 0) line += ", faults 0x" + std::to_string(s.fault_bits);
  return line;
}

// --check: the files the daemon would start from, without opening a device.
int check_setup(const daemon::DaemonOptions& d, bool with_calibration) {
  try {
    if (!d.key_file.empty()) protocol::HmacKey::load(d.key_file);
    if (with_calibration) station::load_station_calibration(d.calibration_dir);
  } catch (const std::exception& e) {
    log::error(e.what());
    return 2;
  }
  log::info("board " + d.board.vendor + "/" + d.board.name + " (" + d.board.source + ") valid" +
            (d.key_file.empty() ? "" : ", key " + d.key_file + " valid") +
            (with_calibration ? ", calibration " + d.calibration_dir.string() + " valid" : ""));
  return 0;
}

int run_daemon(const RunOptions& opt) {
  if (opt.verbose) log::set_level(log::Level::kDebug);
  daemon::DaemonOptions d;
  try {
    d.board = board::load_board_config(opt.board_file);
  } catch (const board::BoardError& e) {
    log::error(e.what());
    return 2;
  }
  d.calibration_dir = opt.calibration_dir.empty() ? kDefaultCalibrationDir : opt.calibration_dir;
  d.state_dir = opt.state_dir.empty() ? default_state_dir() : opt.state_dir;
  d.key_file = opt.key_file;
  d.port = opt.port;
  d.bind_address = opt.bind_address;
  d.replay_window = opt.replay_window;
  d.max_clients = opt.max_clients;
  d.watchdog_timeout = opt.watchdog_timeout;
  d.station.job.tracking_timeout = opt.tracking_timeout;
  d.station.job.max_estimate_age = opt.max_estimate_age;
  d.tracking.grab_timeout = opt.camera_timeout;
  d.station.firmware_version = kVersion;

  if (opt.check_only) return check_setup(d, !opt.calibration_dir.empty());

  // Before any thread starts, so that every thread inherits the blocked signals.
  StopSignal stop;
  hal::SafetySupervisor::install_process_guards();
  std::unique_ptr<daemon::EdgeDaemon> edge;
  try {
    edge = std::make_unique<daemon::EdgeDaemon>(std::move(d), clock::monotonic_clock());
  } catch (const std::exception& e) {
    log::error(e.what());
    sd_notifyf(0, "STATUS=failed: %s", e.what());
    return 2;
  }
  log::info(std::string("dentmark-edge ") + kVersion + ": " + edge->describe());
  try {
    edge->start();
  } catch (const std::exception& e) {
    log::error(e.what());
    sd_notifyf(0, "STATUS=failed: %s", e.what());
    return 1;
  }
  sd_notifyf(0, "READY=1\nSTATUS=%s", status_line(edge->station().status()).c_str());
  std::uint64_t watchdog_usec = 0;
  const bool watchdog = sd_watchdog_enabled(0, &watchdog_usec) > 0;
  log::info(
      "running; SIGINT or SIGTERM stops" +
      (watchdog ? std::string("; systemd watchdog ") + std::to_string(watchdog_usec / 1000) + " ms" : ""));
  std::string last_status;
  // systemd's advice: feed the watchdog at half its period or more often. A quarter
  // leaves room for a slow turn; every turn (10 per second) would cost the service
  // manager a message each, which on a slow CPU is a real share of it.
  const auto feed_period = std::chrono::microseconds(watchdog_usec / 4);
  auto last_feed = std::chrono::steady_clock::now() - feed_period;
  while (!stop.wait_for(std::chrono::milliseconds(100))) {
    // The watchdog is fed only while the station answers: a hung station lock is a restart.
    const std::string now = status_line(edge->station().status());
    if (watchdog && std::chrono::steady_clock::now() - last_feed >= feed_period) {
      sd_notify(0, "WATCHDOG=1");
      last_feed = std::chrono::steady_clock::now();
    }
    if (now != last_status) {
      sd_notifyf(0, "STATUS=%s", now.c_str());
      last_status = now;
    }
  }
  sd_notify(0, "STOPPING=1");
  log::info("signal " + std::to_string(stop.signal_number()) +
            " received; stopping (valve closed, robot stopped)");
  edge->stop();
  return 0;
}

}  // namespace

void register_run(CLI::App& app) {
  auto opt = std::make_shared<RunOptions>();
  CLI::App* run =
      app.add_subcommand("run", "Run the edge daemon: take jobs, track the panel, mark it, report");
  run->add_option("--board", opt->board_file, "Board file (boards/<vendor>/<board>/board.yaml)")->required();
  run->add_option("--calibration", opt->calibration_dir,
                  "Calibration folder: stereo.yaml, robot.yaml, scanner.yaml, models/ (default: "
                  "/etc/dentmark/calibration)");
  run->add_option("--state-dir", opt->state_dir,
                  "Job store (default: $STATE_DIRECTORY, else /var/lib/dentmark)");
  run->add_flag("--check", opt->check_only,
                "Validate the board file, the key file and (when given) the calibration folder, then exit");
  run->add_flag("-v,--verbose", opt->verbose, "Debug logging");
  run->add_option("--port", opt->port,
                  "Link port (overrides the board's link.port; 0 = any free port, logged)")
      ->check(CLI::Range(0, 65535));
  run->add_option("--bind", opt->bind_address, "Link address to listen on (IPv4)")->capture_default_str();
  run->add_option("--key", opt->key_file, "Pre-shared HMAC-SHA-256 key file (hex); refuses unsigned frames");
  run->add_option("--replay-window", opt->replay_window, "Accepted send-time skew and replay memory, s")
      ->check(CLI::Range(0.1, 3600.0));
  run->add_option("--max-clients", opt->max_clients, "Simultaneous link clients")->check(CLI::Range(1, 256));
  run->add_option("--watchdog-timeout", opt->watchdog_timeout,
                  "Valve watchdog: s the control loop may go without a turn before the valve is forced off "
                  "and latched")
      ->check(CLI::Range(0.01, 10.0))
      ->capture_default_str();
  run->add_option("--tracking-timeout", opt->tracking_timeout,
                  "s a job waits for the tracker (the scan's pair found and the kept pairs caught up) before "
                  "giving up on a defect")
      ->check(CLI::Range(0.1, 600.0))
      ->capture_default_str();
  run->add_option("--max-estimate-age", opt->max_estimate_age,
                  "s: tracking counts as lost once the newest trusted tracker estimate is older")
      ->check(CLI::Range(0.01, 60.0))
      ->capture_default_str();
  run->add_option("--camera-timeout", opt->camera_timeout,
                  "s without a stereo pair before the cameras count as lost (a running job then stops)")
      ->check(CLI::Range(0.05, 60.0))
      ->capture_default_str();
  run->callback([opt] { exit_code() = run_daemon(*opt); });
}

}  // namespace dentmark::edge
