#include "dentmark/firmware/daemon/edge_daemon.h"

#include <chrono>
#include <sstream>

#include "dentmark/common/log.h"
#include "dentmark/firmware/hal/gpio/gpio.h"
#include "dentmark/firmware/station/calibration_marker.h"
#include "dentmark/firmware/station/station_link.h"

namespace dentmark::daemon {

namespace {

double system_unix_time() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// Runs 'open' and turns any failure into a DaemonError that says which step failed.
template <typename F>
auto step(const std::string& what, F&& open) {
  try {
    return open();
  } catch (const DaemonError&) {
    throw;
  } catch (const std::exception& e) {
    throw DaemonError(what + ": " + e.what());
  }
}

}  // namespace

EdgeDaemon::EdgeDaemon(DaemonOptions options, clock::Clock& clock)
    : options_(std::move(options)), clock_(clock) {
  if (!options_.unix_time) options_.unix_time = system_unix_time;
  const board::BoardConfig& b = options_.board;
  calibration_ =
      step("calibration", [&] { return station::load_station_calibration(options_.calibration_dir); });
  if (calibration_.stereo.size != cv::Size(b.camera.width, b.camera.height))
    throw DaemonError(options_.calibration_dir.string() + "/stereo.yaml: calibrated for " +
                      std::to_string(calibration_.stereo.size.width) + "x" +
                      std::to_string(calibration_.stereo.size.height) + ", the board's cameras give " +
                      std::to_string(b.camera.width) + "x" + std::to_string(b.camera.height));
  if (const auto why = station::calibration_bad_reason(options_.calibration_dir))
    log::warn((options_.calibration_dir / station::kCalibrationBadFile).string() +
              ": the stored calibration is known bad (" + *why + "); jobs are refused until it is redone");
  if (!options_.key_file.empty())
    key_ = step("link key", [&] { return protocol::HmacKey::load(options_.key_file); });

  // The valve first, closed, under the supervisor before anything else can move.
  gpio_ = step("gpio", [&] { return hal::make_gpio(b, options_.hal, clock_); });
  auto lines = step("gpio lines", [&] { return hal::request_board_lines(*gpio_, b.gpio); });
  part_present_ = std::move(lines.part_present);
  supervisor_ =
      std::make_unique<hal::SafetySupervisor>(std::move(lines.sprayer_valve), std::move(lines.estop), clock_,
                                              hal::SafetyOptions{options_.watchdog_timeout, 0.002});
  safety_io_ = std::make_unique<station::SupervisedSafety>(*supervisor_, clock_);
  robot_ = step("robot", [&] { return hal::make_robot(b, options_.hal, clock_); });
  camera_left_ =
      step("camera left", [&] { return hal::make_camera(b, hal::StereoSide::kLeft, options_.hal, clock_); });
  camera_right_ = step("camera right",
                       [&] { return hal::make_camera(b, hal::StereoSide::kRight, options_.hal, clock_); });
  store_ = step("state directory", [&] { return std::make_unique<station::JobStore>(options_.state_dir); });

  station::CameraTrackingConfig tc = options_.tracking;
  tc.calibration = calibration_.stereo;
  tc.models_dir = calibration_.models_dir;
  tc.max_skew = b.camera.max_skew;
  tc.trust = options_.station.job.trust;  // predicted from the estimates the job steers by
  if (options_.tracking_override) {
    tracking_ = options_.tracking_override(calibration_);
  } else {
    auto cameras = std::make_unique<station::CameraTracking>(*camera_left_, *camera_right_, clock_, tc);
    cameras_ = cameras.get();
    tracking_ = std::move(cameras);
  }

  station::StationConfig sc = options_.station;
  sc.job.planner.chain.T_base_camL = calibration_.T_base_camL;
  sc.job.planner.chain.T_camL_sls = calibration_.T_camL_sls;
  sc.job.planner.limits.workspace_min = b.limits.workspace_min;
  sc.job.planner.limits.workspace_max = b.limits.workspace_max;
  sc.job.planner.limits.max_speed = b.limits.max_speed;
  sc.job.planner.limits.max_acceleration = b.limits.max_acceleration;
  std::function<bool()> part;
  if (part_present_) part = [line = part_present_.get()] { return line->get(); };
  // `calibrate verify` marks the folder when the stored calibration no longer holds:
  // fault bit 5 and jobs refused while the marker exists (read on every status and job).
  auto calibration_faults = [dir = options_.calibration_dir] { return station::calibration_faults(dir); };
  station_ = std::make_unique<station::Station>(
      station::StationDevices{*robot_, *safety_io_, clock_, *tracking_, part, calibration_faults,
                              options_.unix_time},
      *store_, sc);

  link::ServerOptions so;
  so.bind_address = options_.bind_address;
  so.port = static_cast<std::uint16_t>(options_.port >= 0 ? options_.port : b.link.port);
  so.key = key_ ? &*key_ : nullptr;
  so.replay_window = options_.replay_window;
  so.max_clients = options_.max_clients;
  so.clock = options_.unix_time;
  link::Handler handler = station::link_handler(*station_, clock_);
  if (options_.before_request || options_.after_request)
    handler = [inner = std::move(handler), before = options_.before_request, after = options_.after_request](
                  const protocol::Decoded& d, std::span<const std::uint8_t> f) {
      if (before) before(d);
      auto reply = inner(d, f);
      if (after) after(d);
      return reply;
    };
  server_ = std::make_unique<link::LinkServer>(so, std::move(handler));
}

EdgeDaemon::~EdgeDaemon() {
  stop();
}

void EdgeDaemon::start() {
  step("state directory", [&] {
    station_->start();
    return 0;
  });
  step("cameras", [&] {
    if (cameras_) cameras_->start();
    return 0;
  });
  step("link", [&] {
    server_->start();
    return 0;
  });
  started_ = true;
  log::info("link: listening on port " + std::to_string(server_->port()) +
            (key_ ? " (HMAC-SHA-256 required)" : " (unauthenticated: no --key)"));
}

void EdgeDaemon::stop() {
  // Nothing more goes out; stopping the station then wakes the link threads that
  // follow its job, so the link's stop need not wait out a heartbeat.
  if (server_) server_->begin_stop();
  if (station_) station_->stop();
  if (server_) server_->stop();
  if (cameras_) cameras_->stop();
  if (supervisor_) supervisor_->close_valve();
  if (robot_ && started_) {
    try {
      robot_->disconnect();
    } catch (const std::exception& e) {
      log::warn(std::string("robot: disconnect: ") + e.what());
    }
  }
  started_ = false;
}

std::string EdgeDaemon::describe() const {
  const board::BoardConfig& b = options_.board;
  std::ostringstream os;
  os << "board " << b.vendor << "/" << b.name << ": camera " << to_string(b.camera.backend) << " "
     << b.camera.width << "x" << b.camera.height << ", robot modbus " << to_string(b.modbus.transport) << " ";
  if (b.modbus.transport == board::ModbusTransport::kTcp)
    os << b.modbus.host << ":" << b.modbus.port;
  else
    os << b.modbus.device << " " << b.modbus.baud << " " << b.modbus.parity;
  os << ", gpio " << (b.gpio.backend == board::GpioBackend::kSim ? "sim" : "chardev") << " (valve '"
     << b.gpio.sprayer_valve.name << "', e-stop '" << b.gpio.estop.name << "'"
     << (b.gpio.part_present.name.empty() ? ", no part sensor" : ", part '" + b.gpio.part_present.name + "'")
     << "), state " << options_.state_dir.string();
  return os.str();
}

}  // namespace dentmark::daemon
