#include "dentmark/firmware/simulation/station_sim.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <numbers>
#include <optional>
#include <random>
#include <thread>

#include "dentmark/common/clock/clock.h"
#include "dentmark/common/log.h"
#include "dentmark/common/protocol/job_session.h"
#include "dentmark/firmware/board/board_config.h"
#include "dentmark/firmware/daemon/edge_daemon.h"
#include "dentmark/firmware/hal/board_hal.h"
#include "dentmark/firmware/hal/gpio/sim_gpio.h"
#include "dentmark/firmware/simulation/restartable_daemon.h"
#include "dentmark/firmware/simulation/self_calibration.h"
#include "dentmark/firmware/station/station_calibration.h"
#include "dentmark/firmware/track/panel_model.h"
#include "dentmark/sim/robot/robot_simulator.h"
#include "dentmark/sim/stereo/stereo_renderer.h"

namespace dentmark::simulation {
namespace fs = std::filesystem;

namespace {

// The twin's "Unix time": its simulated clock from a fixed epoch, so that the host's
// stamps (scan_time, send_time) and the daemon's reports are on one line.
constexpr double kEpoch = 1.75e9;

// Real-time budgets of the twin's host side: on the lock-step clock a job takes as long
// as its computation, so these only catch a twin that hangs.
constexpr double kRealReplyTimeout = 30.0;  // s for the edge's Ack
constexpr double kRealJobTimeout = 1800.0;  // s for the whole job
constexpr double kRealSilence = 120.0;      // s without a message from the edge
constexpr double kJobEndGrace = 60.0;       // simulated s from the last report to the job's end
// A killed daemon's restart: systemd's RestartSec (packaging/systemd/dentmark-edge.service).
constexpr double kRestartAfter = 1.0;

// A frame's own noise seed. cv::RNG's first draws from nearby seeds are nearly the
// same, which would turn sensor noise into a fixed pattern the door slides over (and
// the tracker sticks to): the seeds are spread by SplitMix64 first.
std::uint64_t mix_seed(std::uint64_t seed, std::uint64_t stream) {
  std::uint64_t z = seed * 0x9E3779B97F4A7C15ull + stream + 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return (z ^ (z >> 31)) | 1u;  // cv::RNG takes 0 as 'default seed'
}

// The panel's true motion, as a perfect tracker would report it (diagnostics).
class TruthMotion final : public station::MotionSource {
 public:
  TruthMotion(const sim::stereo::PanelMotion& motion, clock::Clock& clock, double t_scan)
      : motion_(motion), clock_(clock), T_scan_camL_(motion.T_camL_panel(t_scan).inverse()) {}
  std::optional<station::MotionEstimate> latest() override {
    station::MotionEstimate e;
    e.t = clock_.now();
    e.M_camL = predict(e.t);
    e.ok = true;
    e.quality = 1.0;
    e.features = 10;
    return e;
  }
  // M(t) from the job's scan on (motion_source.h).
  Transform predict(double t) override { return motion_.T_camL_panel(t) * T_scan_camL_; }

 private:
  const sim::stereo::PanelMotion& motion_;
  clock::Clock& clock_;
  const Transform T_scan_camL_;  // the panel's pose at the scan, inverted
};

class TruthTracking final : public station::PanelTracking {
 public:
  TruthTracking(const sim::stereo::PanelMotion& motion, clock::Clock& clock)
      : motion_(motion), clock_(clock) {}
  std::optional<std::string> refuse(const protocol::DefectList&) override { return std::nullopt; }
  std::unique_ptr<station::MotionSource> start(const protocol::DefectList&, double t_scan) override {
    return std::make_unique<TruthMotion>(motion_, clock_, t_scan);
  }

 private:
  const sim::stereo::PanelMotion& motion_;
  clock::Clock& clock_;
};

// A folder of its own, removed with everything in it when the scenario ends.
struct ScratchDir {
  ScratchDir() {
    std::random_device rd;
    path = fs::temp_directory_path() /
           ("dentmark-twin-" + std::to_string(::getpid()) + "-" + std::to_string(rd()));
    fs::create_directories(path / "calibration" / "models");
  }
  ~ScratchDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  fs::path path;
};

// The station's calibration folder as commissioning would leave it: the rig's stereo
// calibration, the robot and scanner transforms with the scenario's calibration
// errors, and the door's panel model taught on the scan's frame.
// With a self-calibration the three files are the ones the calibration commands made.
void commission(const Workcell& cell, const sim::stereo::StereoRenderer& renderer,
                const std::string& panel_id, const fs::path& dir, const SelfCalibrationResult* self) {
  if (self != nullptr) {
    fs::copy_file(self->stereo_yaml, dir / "stereo.yaml", fs::copy_options::overwrite_existing);
    fs::copy_file(self->robot_yaml, dir / "robot.yaml", fs::copy_options::overwrite_existing);
    fs::copy_file(self->scanner_yaml, dir / "scanner.yaml", fs::copy_options::overwrite_existing);
  } else {
    sim::stereo::write_stereo_yaml(cell.rig, dir / "stereo.yaml");
    station::save_transform(dir / "robot.yaml", "T_base_camL", cell.T_base_camL_est, 0.0);
    station::save_transform(dir / "scanner.yaml", "T_camL_sls", cell.T_camL_sls_est, 0.0);
  }
  const Transform pose0 = cell.motion.T_camL_panel(0.0);
  cv::RNG rng(1);
  const cv::Mat left = renderer.render(sim::stereo::Eye::kLeft, pose0, {}, rng);
  const cv::Mat right = renderer.render(sim::stereo::Eye::kRight, pose0, {}, rng);
  std::vector<Eigen::Vector3d> p_camL;
  std::vector<cv::Point2f> pl, pr;
  for (const auto& q : cell.door.features) {
    const Eigen::Vector3d p(q.x(), q.y(), 0.0);
    p_camL.push_back(pose0 * p);
    const cv::Point2d a = renderer.project(sim::stereo::Eye::kLeft, pose0, p);
    const cv::Point2d b = renderer.project(sim::stereo::Eye::kRight, pose0, p);
    pl.emplace_back(static_cast<float>(a.x), static_cast<float>(a.y));
    pr.emplace_back(static_cast<float>(b.x), static_cast<float>(b.y));
  }
  track::save_panel_model(track::make_panel_model(left, right, p_camL, pl, pr),
                          dir / "models" / (panel_id + ".yaml"));
}

std::string twin_board_file(const SimulationOptions& sim) {
  if (!sim.board_file.empty()) return sim.board_file;
  return std::string(DENTMARK_SOURCE_DIR) + "/boards/sim/twin/board.yaml";
}

// Scores each spray against the true defect nearest to what was sent for it.
template <typename Result>
void score(Result& result, const Workcell& cell, const protocol::DefectList& list, const ScanTruth& truth,
           const std::vector<sim::robot::SprayRecord>& sprays, double standoff) {
  std::vector<protocol::Mark> marked;
  for (const protocol::Mark& m : result.report.marks)
    if (m.outcome == protocol::MarkOutcome::kMarked) marked.push_back(m);
  std::sort(marked.begin(), marked.end(), [](const auto& a, const auto& b) { return a.time < b.time; });
  result.marked = static_cast<int>(marked.size());
  for (std::size_t k = 0; k < marked.size() && k < sprays.size(); ++k) {
    const protocol::Mark& m = marked[k];
    const sim::robot::SprayRecord& spray = sprays[k];
    const auto sent = std::find_if(list.defects.begin(), list.defects.end(),
                                   [&](const protocol::Defect& d) { return d.id == m.defect_id; });
    int best = -1;
    double best_d = 0.01;
    for (std::size_t i = 0; i < truth.defects.size(); ++i) {
      const double d = (truth.defects[i].position - sent->position).norm();
      if (d < best_d) best_d = d, best = static_cast<int>(i);
    }
    if (best < 0) {
      ++result.unmatched_marks;
      continue;
    }
    const TruthDefect& td = truth.defects[static_cast<std::size_t>(best)];
    const BasePoint p = true_in_base(cell, td.position, td.normal, spray.time);
    MarkError e;
    e.defect_id = m.defect_id;
    e.truth_index = best;
    e.t_spray = spray.time;
    e.error_base = spray.T_base_tip.translation() - (p.position + standoff * p.normal);
    result.errors.push_back(e);
  }
  for (const MarkError& e : result.errors) {
    result.mean_abs += e.error_base.cwiseAbs() / static_cast<double>(result.errors.size());
    result.max_abs = result.max_abs.cwiseMax(e.error_base.cwiseAbs());
  }
}

// The host inside the twin: the code of `dentmark send --wait` (JobSession). The scan
// was taken at t = 0; the list goes out while time stands still, then the line runs.
protocol::JobOutcome run_host(protocol::DefectList& list, std::uint16_t port, clock::LockstepClock& clock,
                              const std::function<void()>& start_time, double t_scan = 0.0) {
  list.scan_time = kEpoch + t_scan;
  protocol::ClientOptions co;
  co.host = "127.0.0.1";
  co.port = port;
  co.clock = [&clock] { return kEpoch + clock.now(); };
  co.reply_timeout = std::chrono::milliseconds(static_cast<long>(1000 * kRealReplyTimeout));
  protocol::JobSession host(co);
  try {
    host.send(list);
    start_time();
    protocol::JobWaitOptions wo;
    wo.timeout = kRealJobTimeout;
    wo.silence = kRealSilence;
    return host.wait(list, wo);
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string("the twin's host side: ") + e.what());
  }
}

// An outside host (`dentmark send --wait`) sends the list and collects the reports;
// the twin waits for the list, then for the job to end, and reads the same outcomes
// from the station.
protocol::JobOutcome serve_host(const protocol::DefectList& list, RestartableDaemon& daemon,
                                const std::atomic<bool>& list_arrived, const SimulationOptions& sim) {
  log::info("twin: waiting for the host's list (job " + std::to_string(list.job_id) +
            "): dentmark send FILE --to 127.0.0.1:" + std::to_string(daemon.port()) + " --wait");
  const auto now = [] { return std::chrono::steady_clock::now(); };
  const auto list_deadline = now() + std::chrono::duration<double>(sim.serve_timeout);
  while (!list_arrived && now() < list_deadline) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  if (!list_arrived)
    throw std::runtime_error("no defect list came within " + std::to_string(sim.serve_timeout) + " s");
  const auto job_deadline = now() + std::chrono::duration<double>(kRealJobTimeout);
  while (now() < job_deadline) {
    const auto edge = daemon.current();  // empty while a killed daemon restarts
    const auto reports = edge ? edge->station().reports(list.job_id) : std::nullopt;
    if (reports && reports->marks.size() >= list.defects.size() && edge->station().wait_idle(0.0)) {
      protocol::JobOutcome outcome;
      for (const protocol::Mark& m : reports->marks) outcome.marks[m.defect_id] = m;
      outcome.complete = true;
      return outcome;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  throw std::runtime_error("job " + std::to_string(list.job_id) + " did not end in time");
}

// From the records of the valve line, the robot's tip and the reports up to t_end (the
// next job's scan, or the end): how long after the first fault the station was safe
// for good (ScenarioResult).
void time_to_safe(ScenarioResult& result, double t_fault, double t_end,
                  const std::vector<hal::EdgeRecord>& edges, const std::string& valve,
                  const std::vector<sim::robot::TipSample>& tip) {
  result.fault_time = t_fault;
  for (const hal::EdgeRecord& e : edges)
    if (e.line == valve && e.time < t_fault) result.valve_open_at_fault = e.active;
  for (const sim::robot::TipSample& sample : tip)
    if (sample.time < t_fault) result.robot_speed_at_fault = sample.speed;
  // The valve's last closing after the fault (it stays closed from then on); a request
  // of the line (a restarted daemon's) records a closed line that was closed already.
  double closed = t_fault;
  bool open = result.valve_open_at_fault;
  for (const hal::EdgeRecord& e : edges) {
    if (e.line != valve || e.time < t_fault || e.time >= t_end) continue;
    if (!e.active && open) closed = e.time;
    open = e.active;
  }
  result.valve_closed_after = closed - t_fault;
  // The first sample at rest after the last one in motion (the simulator records the
  // instant a move or a braking ends).
  double still = t_fault;
  for (std::size_t i = 0; i < tip.size() && tip[i].time < t_end; ++i)
    if (tip[i].time >= t_fault && tip[i].speed > 0.0)
      still = i + 1 < tip.size() ? tip[i + 1].time : tip[i].time;
  result.robot_still_after = still - t_fault;
  double reported = t_fault;
  for (const protocol::Mark& m : result.report.marks) reported = std::max(reported, m.time);
  result.reported_after = reported - t_fault;
}

// When the station gave up on the panel after a camera or tracking fault: the first
// defect it reported tracking_lost.
void fault_detection(ScenarioResult& result, double t_fault) {
  double detected = std::numeric_limits<double>::infinity();
  for (const protocol::Mark& m : result.report.marks)
    if (m.reason == protocol::MarkReason::kTrackingLost && m.time >= t_fault)
      detected = std::min(detected, m.time);
  result.detected_after = std::isfinite(detected) ? detected - t_fault : -1.0;
}

}  // namespace

namespace {
constexpr std::pair<FaultKind, const char*> kFaultNames[] = {
    {FaultKind::kEstop, "estop"},
    {FaultKind::kRobotLink, "robot-link"},
    {FaultKind::kRobotLinkBlip, "robot-blip"},
    {FaultKind::kRobotFault, "robot-fault"},
    {FaultKind::kCamera, "camera"},
    {FaultKind::kTrackingLost, "tracking"},
    {FaultKind::kDaemonKill, "daemon-kill"},
};
}  // namespace

const char* to_string(FaultKind kind) {
  for (const auto& [k, name] : kFaultNames)
    if (k == kind) return name;
  return "?";
}

Fault parse_fault(const std::string& text) {
  const auto at = text.find('@');
  std::string names;
  for (const auto& [k, name] : kFaultNames) names += std::string(names.empty() ? "" : ", ") + name;
  if (at == std::string::npos)
    throw std::invalid_argument("fault '" + text + "': expected KIND@SECONDS, KIND one of " + names);
  Fault f;
  bool known = false;
  for (const auto& [k, name] : kFaultNames)
    if (text.compare(0, at, name) == 0 && std::string(name).size() == at) f.kind = k, known = true;
  if (!known) throw std::invalid_argument("fault '" + text + "': unknown kind, expected one of " + names);
  std::size_t used = 0;
  try {
    f.after = std::stod(text.substr(at + 1), &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() - at - 1 || !(f.after >= 0.0) || f.after > 3600.0)
    throw std::invalid_argument("fault '" + text + "': the time after marking starts must be 0..3600 s");
  return f;
}

namespace {

// The twin's board: the simulation board file with the scenario's cameras and the
// workcell's limits.
board::BoardConfig twin_board(const SimulationOptions& sim, const ScenarioOptions& scenario,
                              const Workcell& cell) {
  board::BoardConfig board = board::load_board_config(twin_board_file(sim));
  board.camera.width = scenario.width;
  board.camera.height = scenario.height;
  board.limits.workspace_min = cell.workspace_min;
  board.limits.workspace_max = cell.workspace_max;
  return board;
}

// The robot: the workcell's limits and home, a fixed absolute accuracy error drawn from
// the scenario's seed, and its repeatability.
sim::robot::RobotSimConfig robot_config(const ScenarioOptions& scenario, const Workcell& cell,
                                        const board::BoardConfig& board) {
  std::mt19937_64 rng(scenario.seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  sim::robot::RobotSimConfig c;
  c.workspace_min = cell.workspace_min;
  c.workspace_max = cell.workspace_max;
  c.home = cell.robot_home;
  c.max_speed = board.limits.max_speed;
  c.max_acceleration = board.limits.max_acceleration;
  c.accuracy_error = make_transform_rotvec(
      Eigen::Vector3d::Zero(), scenario.robot_accuracy * Eigen::Vector3d(unit(rng), unit(rng), unit(rng)));
  c.repeatability = scenario.robot_repeatability;
  c.seed = static_cast<std::uint32_t>(scenario.seed);
  c.heartbeat_timeout = 0.5;
  return c;
}

// The cameras' view: the door rendered where it truly is, with the robot's arm in view
// and lighting drift; the camera and tracking faults act here.
class DoorCameras {
 public:
  DoorCameras(const Workcell& cell, const ScenarioOptions& scenario, const SimulationOptions& sim,
              sim::robot::RobotSimulator& robot, clock::Clock& clock)
      : cell_(cell),
        renderer_(cell.rig, cell.door),
        scenario_(scenario),
        sim_(sim),
        robot_(robot),
        clock_(clock) {}

  cv::Mat render(sim::stereo::Eye eye, double t) const {
    if (dead) return cv::Mat();  // the driver's error: no image
    sim::stereo::RenderConditions c;
    c.gain = 1.0 + sim_.lighting * std::sin(2.0 * std::numbers::pi * t / 40.0);
    if (eye == sim::stereo::Eye::kRight) c.gain *= 0.96, c.offset = 3.0;
    if (sim_.arm_occludes) {
      const Transform T_camL_base = cell_.T_base_camL_true.inverse();
      const Transform tip = robot_.true_pose();
      sim::stereo::Occluder arm;
      arm.a = T_camL_base * (tip.translation() - 0.12 * tip.linear().col(2));
      arm.b = T_camL_base * Eigen::Vector3d(-0.3, 0.9, 0.2);  // shoulder below the line (floor-mounted robot)
      arm.radius = 0.04;
      c.occluder = arm;
    }
    // Each frame's noise from its own seed: a frame is the same whichever thread asks first.
    const auto frame = static_cast<std::uint64_t>(std::llround(t * scenario_.fps));
    cv::RNG noise(mix_seed(scenario_.seed, frame * 2u + (eye == sim::stereo::Eye::kRight ? 1u : 0u)));
    Transform pose = cell_.motion.T_camL_panel(t);
    if (panel_gone) pose.translation().x() += 4.0;  // off the line: out of both views
    // Rendering takes no simulated time: the cameras expose at their rate whatever this
    // machine's speed.
    clock_.begin_work();
    cv::Mat image = renderer_.render(eye, pose, c, noise);
    clock_.end_work();
    return image;
  }
  const sim::stereo::StereoRenderer& renderer() const { return renderer_; }

  std::atomic<bool> dead{false}, panel_gone{false};

 private:
  const Workcell& cell_;
  const sim::stereo::StereoRenderer renderer_;
  const ScenarioOptions& scenario_;
  const SimulationOptions& sim_;
  sim::robot::RobotSimulator& robot_;
  clock::Clock& clock_;
};

// Starts the line once the list is out, and ends its wait when the scenario is over.
// With a next job: the host says when the first job has ended; the line says (time held)
// when the faults are cleared and the door can be scanned again.
struct LineStop {
  std::mutex mutex;
  std::condition_variable changed;             // waited on through the clock (the line)
  std::condition_variable next_ready_changed;  // waited on in real time (the host side)
  bool started = false;
  bool done = false;
  bool first_job_over = false;
  bool next_ready = false;
  double t_next = 0.0;  // the next job's scan (the clock held from then until it is sent)
};

// Waits on the twin's clock until t; false when the scenario ended first, or (with
// 'or_job_over') the first job did.
bool line_wait_until(clock::Clock& clock, LineStop& stop, double t, bool or_job_over = false) {
  std::unique_lock lock(stop.mutex);
  const auto over = [&] { return stop.done || (or_job_over && stop.first_job_over); };
  while (!over() && !stop.started)
    clock.wait_until(lock, stop.changed, std::numeric_limits<double>::infinity());
  while (!over() && clock.now() < t) clock.wait_until(lock, stop.changed, t);
  return !over();
}

// Clears an injected fault where it clears (SimulationOptions::next_job).
void clear_fault(FaultKind kind, const board::BoardConfig& board, hal::SimGpio& gpio,
                 sim::robot::RobotSimulator& robot, DoorCameras& cameras) {
  switch (kind) {
    case FaultKind::kEstop:
      gpio.drive(board.gpio.estop.name, false);
      break;
    case FaultKind::kRobotLink:
    case FaultKind::kRobotLinkBlip:
      robot.inject_drop(0);
      break;
    case FaultKind::kRobotFault:
      robot.clear_fault();
      break;
    case FaultKind::kCamera:
      cameras.dead = false;
      break;
    case FaultKind::kTrackingLost:
      cameras.panel_gone = false;
      break;
    case FaultKind::kDaemonKill:
      break;  // the daemon came back by itself
  }
}

// The next job's turn: once the first job is over, the faults are cleared, and then time
// is held for the host to scan and send the next list.
void prepare_next_job(const std::vector<Fault>& injected, const board::BoardConfig& board,
                      clock::Clock& clock, LineStop& stop, hal::SimGpio& gpio,
                      sim::robot::RobotSimulator& robot, DoorCameras& cameras) {
  constexpr double kClearAfter = 0.5;  // s after the first job's end
  constexpr double kScanAfter = 1.0;   // s after the faults are cleared
  {
    std::unique_lock lock(stop.mutex);
    while (!stop.done && !stop.first_job_over)
      clock.wait_until(lock, stop.changed, std::numeric_limits<double>::infinity());
    if (stop.done) return;
  }
  if (!line_wait_until(clock, stop, clock.now() + kClearAfter)) return;
  for (const Fault& f : injected) clear_fault(f.kind, board, gpio, robot, cameras);
  log::info("twin: faults cleared at t = " + std::to_string(clock.now()) + " s");
  if (!line_wait_until(clock, stop, clock.now() + kScanAfter)) return;
  clock.pause();  // the host resumes it once the next list is out
  {
    std::lock_guard lock(stop.mutex);
    stop.next_ready = true;
    stop.t_next = clock.now();
  }
  stop.next_ready_changed.notify_all();
}

// The line around the station: once time runs, the panel reaches the marking place
// (part-present) at t_mark, and the scenario's faults come after; with a next job, they
// are cleared after the first job and the door is made ready for its second scan.
void run_line(const SimulationOptions& sim, const Workcell& cell, const board::BoardConfig& board,
              clock::Clock& clock, LineStop& stop, hal::SimGpio& gpio, sim::robot::RobotSimulator& robot,
              DoorCameras& cameras, RestartableDaemon& daemon) {
  std::vector<Fault> faults = sim.faults;
  std::sort(faults.begin(), faults.end(), [](const Fault& a, const Fault& b) { return a.after < b.after; });
  if (!line_wait_until(clock, stop, cell.t_mark)) return;
  gpio.drive(board.gpio.part_present.name, true);
  std::vector<Fault> injected;
  for (const Fault& f : faults) {
    // A fault due after the first job has ended is not injected.
    if (!line_wait_until(clock, stop, cell.t_mark + f.after, true)) break;
    injected.push_back(f);
    log::warn(std::string("twin: fault ") + to_string(f.kind) + " at t = " + std::to_string(clock.now()) +
              " s");
    switch (f.kind) {
      case FaultKind::kEstop:
        gpio.drive(board.gpio.estop.name, true);
        break;
      case FaultKind::kRobotLink:
        robot.inject_drop(1 << 30);
        break;
      case FaultKind::kRobotLinkBlip:
        robot.inject_drop(1);
        break;
      case FaultKind::kRobotFault:
        robot.inject_drive_fault();
        break;
      case FaultKind::kCamera:
        cameras.dead = true;
        break;
      case FaultKind::kTrackingLost:
        cameras.panel_gone = true;
        break;
      case FaultKind::kDaemonKill:
        daemon.kill();
        daemon.restart(kRestartAfter);
        break;
    }
  }
  if (sim.next_job) prepare_next_job(injected, board, clock, stop, gpio, robot, cameras);
}

// The station's calibration against the truth: what the self-calibration measured, or
// the errors drawn for the scenario.
void note_calibration(ScenarioResult& result, const Workcell& cell,
                      const std::optional<SelfCalibrationResult>& self) {
  const auto rotation = [](const Transform& a, const Transform& b) {
    return Eigen::AngleAxisd((a.inverse() * b).linear()).angle();
  };
  result.self_calibrated = self.has_value();
  if (self) {
    result.robot_calibration_error = self->robot_translation_error;
    result.robot_calibration_rotation = self->robot_rotation_error;
    result.scanner_calibration_error = self->scanner_translation_error;
    result.scanner_calibration_rotation = self->scanner_rotation_error;
    return;
  }
  result.robot_calibration_error =
      (cell.T_base_camL_est.translation() - cell.T_base_camL_true.translation()).norm();
  result.robot_calibration_rotation = rotation(cell.T_base_camL_est, cell.T_base_camL_true);
  result.scanner_calibration_error =
      (cell.T_camL_sls_est.translation() - cell.T_camL_sls_true.translation()).norm();
  result.scanner_calibration_rotation = rotation(cell.T_camL_sls_est, cell.T_camL_sls_true);
}

// The valve line as the simulated GPIO recorded it from t_begin to t_end.
template <typename Result>
void note_valve(Result& result, const hal::SimGpio& gpio, const std::string& valve, double t_begin,
                double t_end) {
  result.valve_open_at_end = false;
  for (const hal::EdgeRecord& e : gpio.edges()) {
    if (e.line != valve || e.time < t_begin || e.time >= t_end) continue;
    result.valve_open_at_end = e.active;
    if (e.active) ++result.valve_pulses;
  }
}

// The sprays from t_begin to t_end.
std::vector<sim::robot::SprayRecord> sprays_between(const std::vector<sim::robot::SprayRecord>& sprays,
                                                    double t_begin, double t_end) {
  std::vector<sim::robot::SprayRecord> out;
  for (const sim::robot::SprayRecord& r : sprays)
    if (r.time >= t_begin && r.time < t_end) out.push_back(r);
  return out;
}

// The door scanned again at t (the scanner's true calibration: the list says where the
// defects then are), under the next job id; defect ids as before.
protocol::DefectList rescanned(const protocol::DefectList& list, const Workcell& cell, double t) {
  protocol::DefectList next = list;
  next.job_id = list.job_id + 1;
  const Transform T_sls_sls0 = cell.T_camL_sls_true.inverse() * cell.motion.motion(t) * cell.T_camL_sls_true;
  for (protocol::Defect& d : next.defects) {
    d.position = T_sls_sls0 * d.position;
    d.normal = T_sls_sls0.linear() * d.normal;
  }
  return next;
}

// The host's reports, in the list's defect order, on the twin's clock.
template <typename Result>
void take_reports(Result& result, const protocol::DefectList& list, const protocol::JobOutcome& outcome) {
  result.report.job_id = list.job_id;
  for (const protocol::Defect& def : list.defects)
    if (const auto it = outcome.marks.find(def.id); it != outcome.marks.end()) {
      protocol::Mark m = it->second;
      m.time -= kEpoch;
      result.report.marks.push_back(m);
    }
}

// What one run recorded for scoring, once the station has stopped.
struct RunRecord {
  protocol::JobOutcome outcome;
  std::optional<std::pair<protocol::DefectList, protocol::JobOutcome>> next;  // the next job's list, outcome
  double t_next = std::numeric_limits<double>::infinity();                    // the next job's scan time
};

// The run's figures against the truth: valve pulses, reports, sprays, the time to safe
// after a fault, and the same for the next job; sprays are split at its scan time.
void score_run(ScenarioResult& result, const RunRecord& run, const ScenarioOptions& scenario,
               const SimulationOptions& sim, const Workcell& cell, const protocol::DefectList& list,
               const ScanTruth& truth, const board::BoardConfig& board, hal::SimGpio& gpio,
               sim::robot::RobotSimulator& robot) {
  constexpr double kNever = std::numeric_limits<double>::infinity();
  const std::string& valve = board.gpio.sprayer_valve.name;
  const std::vector<sim::robot::SprayRecord> sprays = robot.sprays();
  note_valve(result, gpio, valve, 0.0, run.t_next);
  take_reports(result, list, run.outcome);
  score(result, cell, list, truth, sprays_between(sprays, 0.0, run.t_next), scenario.standoff);
  if (!sim.faults.empty()) {
    double first = sim.faults.front().after;
    for (const Fault& f : sim.faults) first = std::min(first, f.after);
    const double t_fault = cell.t_mark + first;
    time_to_safe(result, t_fault, run.t_next, gpio.edges(), valve, robot.trajectory());
    fault_detection(result, t_fault);
  }
  if (run.next) {
    NextJobResult& n = result.next_job.emplace();
    n.t_scan = run.t_next;
    n.defects_sent = static_cast<int>(run.next->first.defects.size());
    note_valve(n, gpio, valve, run.t_next, kNever);
    take_reports(n, run.next->first, run.next->second);
    // Scored against the truth through the first list (same ids, positions at t = 0).
    score(n, cell, list, truth, sprays_between(sprays, run.t_next, kNever), scenario.standoff);
  }
}

// When the twin's clock stands still: until the first list is out (the scan is at t = 0
// exactly, the cameras take their first frame then, and the list arrives then); from a
// job's end until the host side has its reports (the run's figures do not depend on how
// long that takes); and while the line holds it for the next list (prepare_next_job).
class ClockHolds {
 public:
  ClockHolds(clock::LockstepClock& clock, LineStop& line) : clock_(clock), line_(line) {}

  // The first list is out: the line starts and time runs (once).
  void start() {
    if (!waiting_for_list_.exchange(false)) return;
    {
      std::lock_guard lock(line_.mutex);
      line_.started = true;
    }
    clock_.notify_all(line_.changed);
    clock_.resume();
  }
  // A job ended: time stops, once, until release_job_end.
  void hold_at_job_end() {
    if (!job_end_.exchange(true)) clock_.pause();
  }
  void release_job_end() {
    if (job_end_.exchange(false)) clock_.resume();
  }
  // Time runs to the end of the run; a later job end (none is due) stops it no more.
  void release_job_end_for_good() {
    if (job_end_) clock_.resume();
  }
  // The line paused time for the next list; the host side releases it once it is out.
  void hold_for_next() { next_ = true; }
  void release_next() {
    if (next_.exchange(false)) clock_.resume();
  }

 private:
  clock::LockstepClock& clock_;
  LineStop& line_;
  std::atomic<bool> waiting_for_list_{true}, job_end_{false}, next_{false};
};

// The daemon as the twin runs it: the twin's board, scratch calibration and state, the
// rendered cameras, the modelled frame time and the clock's holds. With 'serve', the
// host is outside: its list's age (by its own clock) is run on the line before time starts.
// The daemon's GPIO is the twin's chip, which outlives a killed daemon.
daemon::DaemonOptions twin_daemon_options(const SimulationOptions& sim, const ScenarioOptions& scenario,
                                          const board::BoardConfig& board, const fs::path& scratch,
                                          clock::LockstepClock& clock, ClockHolds& holds,
                                          DoorCameras& cameras, std::atomic<bool>& list_arrived,
                                          const std::shared_ptr<hal::SimGpio>& chip) {
  daemon::DaemonOptions d;
  d.board = board;
  d.calibration_dir = scratch / "calibration";
  d.state_dir = scratch / "state";
  d.port = sim.serve ? sim.serve_port : 0;
  d.bind_address = "127.0.0.1";
  if (sim.serve) {
    d.before_request = [&](const protocol::Decoded& req) {
      const auto* l = std::get_if<protocol::DefectList>(&req.message);
      if (l == nullptr || list_arrived.exchange(true)) return;
      const double age = req.header.send_time - l->scan_time;
      log::info("twin: the host's scan is " + std::to_string(age) + " s old; the line ran meanwhile");
      clock.advance(std::max(0.0, age));
    };
    // Time runs once the list is in (its arrival stamped at the scan's age, not later).
    d.after_request = [&](const protocol::Decoded& req) {
      if (std::holds_alternative<protocol::DefectList>(req.message) && list_arrived) holds.start();
    };
  }
  d.hal.render = [&cameras](double t) { return cameras.render(sim::stereo::Eye::kLeft, t); };
  d.hal.render_right = [&cameras](double t) { return cameras.render(sim::stereo::Eye::kRight, t); };
  d.hal.sim_frame_period = 1.0 / scenario.fps;
  d.hal.sim_chip = chip;
  d.station.job.planner.chain.standoff = scenario.standoff;
  d.station.firmware_version = "twin";
  d.tracking.grab_timeout = 1.0;
  d.tracking.frame_processing_time = sim.frame_processing_time;
  d.unix_time = [&clock] { return kEpoch + clock.now(); };
  return d;
}

// The running twin: what the host side and the shutdown act on.
struct RunningTwin {
  clock::LockstepClock& clock;
  ClockHolds& holds;
  LineStop& line;
  RestartableDaemon& daemon;
};

// Waits for the running daemon's station to be idle.
void wait_station_idle(RestartableDaemon& daemon) {
  if (const auto edge = daemon.current()) edge->station().wait_idle(kJobEndGrace);
}

// The next job, once the first has ended and the line has cleared its faults: the door
// scanned again where it then is, sent while time is held.
std::pair<protocol::DefectList, protocol::JobOutcome> run_next_job(RunningTwin& twin,
                                                                   const protocol::DefectList& list,
                                                                   const Workcell& cell) {
  wait_station_idle(twin.daemon);
  {
    std::lock_guard lock(twin.line.mutex);
    twin.line.first_job_over = true;
  }
  twin.clock.notify_all(twin.line.changed);
  twin.holds.release_job_end();
  double t_next = 0.0;
  {
    std::unique_lock lock(twin.line.mutex);
    if (!twin.line.next_ready_changed.wait_for(lock, std::chrono::duration<double>(kRealReplyTimeout),
                                               [&] { return twin.line.next_ready; }))
      throw std::runtime_error("the twin's line did not clear its faults for the next job");
    twin.holds.hold_for_next();
    t_next = twin.line.t_next;
  }
  protocol::DefectList next = rescanned(list, cell, t_next);
  return {next, run_host(
                    next, twin.daemon.port(), twin.clock, [&] { twin.holds.release_next(); }, t_next)};
}

// The host's side of the run: the list sent (or served to an outside host), its reports
// collected, and with a next job, that one too.
RunRecord run_host_side(RunningTwin& twin, const SimulationOptions& sim, protocol::DefectList& list,
                        const Workcell& cell, std::atomic<bool>& list_arrived) {
  RunRecord run;
  if (sim.serve)
    run.outcome = serve_host(list, twin.daemon, list_arrived, sim);
  else
    run.outcome = run_host(list, twin.daemon.port(), twin.clock, [&] { twin.holds.start(); });
  if (sim.next_job && !sim.serve) run.next = run_next_job(twin, list, cell);
  return run;
}

// Ends the run: time runs until the station is idle (the host may have had every report
// before the job ended), the frame counts are noted, then the line, the daemon and the
// robot stop.
void finish_run(RunningTwin& twin, clock::ParticipantThread& line_thread, sim::robot::RobotSimulator& robot,
                const ScenarioOptions& scenario, ScenarioResult& result) {
  twin.holds.start();
  twin.holds.release_next();
  wait_station_idle(twin.daemon);
  result.sim_seconds = twin.clock.now();
  if (const auto edge = twin.daemon.current(); edge && edge->cameras()) {
    result.frames_tracked = twin.daemon.pairs_captured();
    // The cameras' frames from t = 0 to the end, both included.
    result.frames_offered = static_cast<long>(std::floor(result.sim_seconds * scenario.fps + 1e-6)) + 1;
  }
  twin.holds.release_job_end_for_good();  // time runs again for the shutdown
  {
    std::lock_guard lock(twin.line.mutex);
    twin.line.done = true;
  }
  twin.clock.notify_all(twin.line.changed);
  line_thread.join();
  twin.daemon.stop();
  robot.stop();
}

}  // namespace

ScenarioResult run_scenario(const ScenarioOptions& scenario, const SimulationOptions& sim,
                            const protocol::DefectList& sent_list, const ScanTruth& truth) {
  const auto real_start = std::chrono::steady_clock::now();
  const Workcell cell = make_workcell(scenario, truth.T_sls_panel, truth.panel_width, truth.panel_height);
  protocol::DefectList list = sent_list;
  if (list.panel_id.empty()) list.panel_id = "twin-door";
  board::BoardConfig board = twin_board(sim, scenario, cell);

  clock::LockstepClock clock(0.0);  // held until the list is out
  LineStop line_stop;
  ClockHolds holds(clock, line_stop);
  std::optional<SelfCalibrationResult> self;
  if (!sim.self_calibration_cache.empty())
    self = self_calibrate(cell, board, robot_config(scenario, cell, board), sim.self_calibration_cache);
  auto robot_sim = sim::robot::RobotSimulator::serve_tcp(robot_config(scenario, cell, board), clock);
  board.modbus.host = "127.0.0.1";
  board.modbus.port = robot_sim->port();
  DoorCameras cameras(cell, scenario, sim, *robot_sim, clock);
  ScratchDir scratch;
  commission(cell, cameras.renderer(), list.panel_id, scratch.path / "calibration", self ? &*self : nullptr);

  std::atomic<bool> list_arrived{false};
  hal::HalChoice simulated;
  simulated.simulate = true;
  const auto chip = std::dynamic_pointer_cast<hal::SimGpio>(hal::make_gpio(board, simulated, clock));
  hal::SimGpio& gpio = *chip;
  std::unique_ptr<RestartableDaemon> edge;
  const auto daemon_options = [&](int n) {
    daemon::DaemonOptions d =
        twin_daemon_options(sim, scenario, board, scratch.path, clock, holds, cameras, list_arrived, chip);
    // A killed daemon's job end no longer holds the twin's clock.
    d.station.on_job_end = [&, n](std::uint64_t) {
      if (edge->is_current(n)) holds.hold_at_job_end();
    };
    if (sim.truth_motion)
      d.tracking_override = [&](const station::StationCalibration&) {
        return std::make_unique<TruthTracking>(cell.motion, clock);
      };
    return d;
  };
  // The restarted daemon ends the killed one's job at once: time stands still, as at
  // any job's end, until the host side has its reports.
  edge = std::make_unique<RestartableDaemon>(daemon_options, clock, gpio, *robot_sim,
                                             [&holds] { holds.hold_at_job_end(); });
  clock::ParticipantThread line(
      clock, [&] { run_line(sim, cell, board, clock, line_stop, gpio, *robot_sim, cameras, *edge); });

  ScenarioResult result;
  result.options = scenario;
  note_calibration(result, cell, self);
  result.defects_sent = static_cast<int>(list.defects.size());
  RunningTwin twin{clock, holds, line_stop, *edge};
  RunRecord run;
  try {
    run = run_host_side(twin, sim, list, cell, list_arrived);
  } catch (const std::exception&) {
    finish_run(twin, line, *robot_sim, scenario, result);
    throw;
  }
  finish_run(twin, line, *robot_sim, scenario, result);
  if (run.next) run.t_next = line_stop.t_next;
  score_run(result, run, scenario, sim, cell, list, truth, board, gpio, *robot_sim);
  result.real_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - real_start).count();
  return result;
}

}  // namespace dentmark::simulation
