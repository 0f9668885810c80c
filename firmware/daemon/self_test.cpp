#include "dentmark/firmware/daemon/self_test.h"

#include <functional>
#include <memory>
#include <optional>

#include "dentmark/common/atomic_file.h"
#include "dentmark/common/protocol/hmac_key.h"
#include "dentmark/common/robot_link/register_map.h"
#include "dentmark/firmware/station/calibration_marker.h"
#include "dentmark/firmware/station/job_store.h"
#include "dentmark/firmware/station/station_calibration.h"

namespace dentmark::daemon {

bool SelfTestReport::passed() const {
  for (const SelfTestCheck& c : checks)
    if (!c.passed) return false;
  return !checks.empty();
}

namespace {

std::string size_text(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

// Runs one check: 'body' returns what it found, or throws what is wrong.
class Checks {
 public:
  bool run(const std::string& name, const std::function<std::string()>& body) {
    SelfTestCheck c;
    c.name = name;
    try {
      c.detail = body();
      c.passed = true;
    } catch (const std::exception& e) {
      c.detail = e.what();
    }
    report_.checks.push_back(c);
    return c.passed;
  }
  void skip(const std::string& name, const std::string& why) {
    report_.checks.push_back({name, false, true, why});
  }
  SelfTestReport take() { return std::move(report_); }

 private:
  SelfTestReport report_;
};

std::string check_robot(const board::BoardConfig& board, const hal::HalChoice& choice, clock::Clock& clock) {
  auto robot = hal::make_robot(board, choice, clock);
  robot->connect();
  const hal::RobotStatus s = robot->status();
  robot->disconnect();
  const std::string state =
      std::string(robot_link::to_string(s.state)) + " (faults: " + robot_link::fault_names(s.faults) + ")";
  // A stop the station clears itself at the next job is healthy; a drive fault is not.
  if ((s.faults & ~robot_link::fault::kClearableByStation) != 0)
    throw std::runtime_error("robot reachable but " + state + ": needs the robot's operator");
  return "reachable, " + state;
}

std::string check_camera(const board::BoardConfig& board, hal::StereoSide side, const SelfTestOptions& o,
                         clock::Clock& clock) {
  auto camera = hal::make_camera(board, side, o.hal, clock);
  camera->start();
  const std::optional<hal::Frame> frame = camera->grab(o.camera_timeout);
  camera->stop();
  if (!frame)
    throw std::runtime_error(camera->name() + ": no frame within " + std::to_string(o.camera_timeout) + " s");
  if (frame->image.cols != board.camera.width || frame->image.rows != board.camera.height)
    throw std::runtime_error(camera->name() + ": frames are " +
                             size_text(frame->image.cols, frame->image.rows) + ", the board says " +
                             size_text(board.camera.width, board.camera.height));
  return camera->name() + ": frame " + size_text(frame->image.cols, frame->image.rows);
}

std::string check_state_dir(const std::filesystem::path& dir) {
  const station::JobStore store(dir);
  const std::size_t jobs = store.load().size();
  const std::filesystem::path probe = dir / ".self-test";
  files::write_atomically(probe, "self-test\n");
  std::filesystem::remove(probe);
  return dir.string() + " writable, " + std::to_string(jobs) + " stored jobs readable";
}

}  // namespace

SelfTestReport run_self_test(const SelfTestOptions& o, clock::Clock& clock) {
  Checks checks;
  board::BoardConfig board;
  const bool board_ok = checks.run("board", [&] {
    board = board::load_board_config(o.board_file.string());
    return o.board_file.string() + ": " + board.vendor + "/" + board.name;
  });
  if (!o.key_file.empty())
    checks.run("key", [&] {
      protocol::HmacKey::load(o.key_file);
      return o.key_file + " valid";
    });
  checks.run("calibration", [&] {
    const station::StationCalibration cal = station::load_station_calibration(o.calibration_dir);
    const cv::Size size = cal.stereo.size;
    if (board_ok && size != cv::Size(board.camera.width, board.camera.height))
      throw std::runtime_error((o.calibration_dir / "stereo.yaml").string() + ": calibrated for " +
                               size_text(size.width, size.height) + ", the board's cameras give " +
                               size_text(board.camera.width, board.camera.height));
    if (const auto why = station::calibration_bad_reason(o.calibration_dir))
      throw std::runtime_error((o.calibration_dir / station::kCalibrationBadFile).string() +
                               ": the stored calibration is known bad (" + *why + "): recalibrate");
    return o.calibration_dir.string() + " valid (" + size_text(size.width, size.height) + ")";
  });
  const char* devices[] = {"gpio", "robot", "camera left", "camera right"};
  if (!board_ok) {
    for (const char* name : devices) checks.skip(name, "no valid board file");
  } else {
    checks.run("gpio", [&] {
      auto gpio = hal::make_gpio(board, o.hal, clock);
      const hal::GpioLines lines = hal::request_board_lines(*gpio, board.gpio);
      const bool estop = lines.estop->get();
      return "lines claimed (valve '" + board.gpio.sprayer_valve.name + "' inactive, e-stop '" +
             board.gpio.estop.name + "' " + (estop ? "PRESSED" : "released") + ")";
    });
    checks.run("robot", [&] { return check_robot(board, o.hal, clock); });
    checks.run("camera left", [&] { return check_camera(board, hal::StereoSide::kLeft, o, clock); });
    checks.run("camera right", [&] { return check_camera(board, hal::StereoSide::kRight, o, clock); });
  }
  checks.run("state", [&] { return check_state_dir(o.state_dir); });
  return checks.take();
}

}  // namespace dentmark::daemon
