#include "dentmark/firmware/simulation/station_sim.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <numbers>
#include <random>
#include <thread>

#include "dentmark/common/clock/clock.h"
#include "dentmark/common/log.h"
#include "dentmark/firmware/board/board_config.h"
#include "dentmark/firmware/hal/gpio/sim_gpio.h"
#include "dentmark/firmware/hal/robot/modbus_robot.h"
#include "dentmark/firmware/hal/safety/safety_supervisor.h"
#include "dentmark/firmware/station/job_runner.h"
#include "dentmark/firmware/station/supervised_safety.h"
#include "dentmark/firmware/station/tracking_motion_source.h"
#include "dentmark/sim/robot/robot_simulator.h"
#include "dentmark/sim/stereo/stereo_renderer.h"

namespace dentmark::simulation {
namespace {

// The panel's true motion, as a perfect tracker would report it.
class TruthMotion final : public station::MotionSource {
 public:
  TruthMotion(const stereo::PanelMotion& motion, clock::Clock& clock) : motion_(motion), clock_(clock) {}
  std::optional<station::MotionEstimate> latest() override {
    station::MotionEstimate e;
    e.t = clock_.now();
    e.M_camL = motion_.motion(e.t);
    e.ok = true;
    e.quality = 1.0;
    e.features = 10;
    return e;
  }
  Transform predict(double t) override { return motion_.motion(t); }

 private:
  const stereo::PanelMotion& motion_;
  clock::Clock& clock_;
};

track::StereoCalibration calibration_of(const stereo::StereoRig& rig) {
  track::StereoCalibration c;
  c.size = rig.size;
  c.left.K = rig.left.K;
  c.left.D = rig.left.D.clone();
  c.right.K = rig.right.K;
  c.right.D = rig.right.D.clone();
  c.T_camR_camL = rig.T_camR_camL;
  return c;
}

}  // namespace

ScenarioResult run_scenario(const ScenarioOptions& scenario, const SimulationOptions& sim,
                            const protocol::DefectList& list, const ScanTruth& truth) {
  const auto real_start = std::chrono::steady_clock::now();
  const Workcell cell = make_workcell(scenario, truth.T_sls_panel, truth.panel_width, truth.panel_height);
  clock::SimClock clock(sim.clock_rate);

  // The robot: a Modbus TCP server on loopback with a fixed accuracy error.
  std::mt19937_64 rng(scenario.seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  sim::RobotSimConfig robot_cfg;
  robot_cfg.workspace_min = cell.workspace_min;
  robot_cfg.workspace_max = cell.workspace_max;
  robot_cfg.home = cell.robot_home;
  robot_cfg.accuracy_error = make_transform_rotvec(
      Eigen::Vector3d::Zero(), scenario.robot_accuracy * Eigen::Vector3d(unit(rng), unit(rng), unit(rng)));
  robot_cfg.repeatability = scenario.robot_repeatability;
  robot_cfg.seed = static_cast<std::uint32_t>(scenario.seed);
  robot_cfg.heartbeat_timeout = 0.5 * std::max(1.0, sim.clock_rate);
  auto robot_sim = sim::RobotSimulator::serve_tcp(robot_cfg, clock);
  board::ModbusConfig modbus;
  modbus.transport = board::ModbusTransport::kTcp;
  modbus.host = "127.0.0.1";
  modbus.port = robot_sim->port();
  // Socket timeouts and the heartbeat watchdog are real-time budgets of the link (and
  // of an emulated CPU under qemu); at a fast clock they are scaled to stay that long.
  modbus.timeout = 0.5 * std::max(1.0, sim.clock_rate);
  hal::ModbusRobot robot(modbus, clock);
  robot.connect();

  // The cameras: the door rendered where it truly is, with the arm in view.
  const stereo::StereoRenderer renderer(cell.rig, cell.door);
  const Transform T_camL_base = cell.T_base_camL_true.inverse();
  const double t_end = cell.t_mark + 60.0;
  long next_index = 0;
  cv::RNG render_rng(static_cast<std::uint64_t>(scenario.seed));
  std::mutex render_mutex;
  const auto frames = [&]() -> std::optional<station::StereoFrame> {
    std::lock_guard lock(render_mutex);
    // Like a camera, deliver the newest exposure: frames missed while busy are dropped.
    // The first pair (it seeds the tracker, whose M(t) is relative to it) is the one the
    // cameras took with the scan at t = 0; later ones are the newest exposure.
    if (next_index > 0)
      next_index = std::max(next_index, static_cast<long>(std::floor(clock.now() * scenario.fps)));
    const double t = next_index / scenario.fps;
    if (t > t_end) return std::nullopt;
    clock.sleep_until(t);
    stereo::RenderConditions c;
    c.gain = 1.0 + sim.lighting * std::sin(2.0 * std::numbers::pi * t / 40.0);
    if (sim.arm_occludes) {
      const Transform tip = robot_sim->true_pose();
      stereo::Occluder arm;
      arm.a = T_camL_base * (tip.translation() - 0.12 * tip.linear().col(2));
      arm.b = T_camL_base *
              Eigen::Vector3d(-0.3, 0.9, 0.2);  // shoulder below the line, like a floor-mounted robot
      arm.radius = 0.04;
      c.occluder = arm;
    }
    const Transform pose = cell.motion.T_camL_panel(t);
    station::StereoFrame f;
    f.t = t;
    f.index = next_index++;
    f.left = renderer.render(stereo::Eye::kLeft, pose, c, render_rng);
    stereo::RenderConditions cr = c;
    cr.gain *= 0.96;
    cr.offset = 3.0;
    f.right = renderer.render(stereo::Eye::kRight, pose, cr, render_rng);
    return f;
  };
  // Seeds as an operator would click them: a few pixels off the true corners.
  std::vector<cv::Point2f> seeds;
  std::uniform_real_distribution<double> click(-3.0, 3.0);
  for (const auto& q : cell.door.features) {
    const cv::Point2d p =
        renderer.project(stereo::Eye::kRight, cell.motion.T_camL_panel(0.0), {q.x(), q.y(), 0.0});
    seeds.emplace_back(static_cast<float>(p.x + click(rng)), static_cast<float>(p.y + click(rng)));
  }
  std::unique_ptr<station::TrackingMotionSource> tracking;
  TruthMotion truth_motion(cell.motion, clock);
  if (!sim.truth_motion)
    tracking = std::make_unique<station::TrackingMotionSource>(calibration_of(cell.rig), seeds, frames);
  station::MotionSource& motion = tracking ? static_cast<station::MotionSource&>(*tracking)
                                           : static_cast<station::MotionSource&>(truth_motion);

  // The sprayer valve and e-stop through the hal's safety supervisor on simulated lines;
  // its watchdog allows a second of real time, enough for an emulated CPU.
  const board::GpioLine valve_line{"sprayer-valve", false}, estop_line{"estop", true};
  hal::SimGpio gpio({valve_line.name, estop_line.name}, clock);
  hal::SafetySupervisor supervisor(gpio.request_output(valve_line, false), gpio.request_input(estop_line),
                                   clock, hal::SafetyOptions{std::max(1.0, sim.clock_rate), 0.002});
  station::SupervisedSafety safety(supervisor, clock);
  station::JobConfig job;
  job.planner.chain.T_base_camL = cell.T_base_camL_est;
  job.planner.chain.T_camL_sls = cell.T_camL_sls_est;
  job.planner.chain.standoff = scenario.standoff;
  job.planner.limits.workspace_min = cell.workspace_min;
  job.planner.limits.workspace_max = cell.workspace_max;
  job.planner.limits.max_speed = robot_cfg.max_speed;
  job.planner.limits.max_acceleration = robot_cfg.max_acceleration;
  station::JobRunner runner(robot, safety, motion, clock, job);

  clock.sleep_until(cell.t_mark);
  std::thread estop;
  std::atomic<bool> done{false};
  if (sim.estop_after >= 0.0)
    estop = std::thread([&] {
      const double at = cell.t_mark + sim.estop_after;
      while (!done && clock.now() < at) clock.sleep_for(0.005);
      if (!done) gpio.drive(estop_line.name, true);
    });
  ScenarioResult result;
  result.options = scenario;
  result.defects_sent = static_cast<int>(list.defects.size());
  result.report = runner.run(list, 0.0);
  result.sim_seconds = clock.now();
  done = true;
  if (estop.joinable()) estop.join();
  result.valve_open_at_end = gpio.level(valve_line.name);
  if (tracking) {
    tracking->stop();
    result.frames_tracked = tracking->frames_tracked();
    result.frames_failed = tracking->frames_failed();
    result.frames_offered = static_cast<long>(result.sim_seconds * scenario.fps);
  }
  robot.disconnect();
  robot_sim->stop();
  for (const hal::EdgeRecord& e : gpio.edges())
    if (e.line == valve_line.name && e.active) ++result.valve_pulses;

  // Score each spray against the true defect nearest to what was sent for it.
  const auto sprays = robot_sim->sprays();
  std::size_t k = 0;
  for (const protocol::Mark& m : result.report.marks) {
    if (m.outcome != protocol::MarkOutcome::kMarked) continue;
    ++result.marked;
    if (k >= sprays.size()) break;
    const sim::SprayRecord& spray = sprays[k++];
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
    e.error_base = spray.T_base_tip.translation() - (p.position + scenario.standoff * p.normal);
    result.errors.push_back(e);
  }
  for (const MarkError& e : result.errors) {
    result.mean_abs += e.error_base.cwiseAbs() / static_cast<double>(result.errors.size());
    result.max_abs = result.max_abs.cwiseMax(e.error_base.cwiseAbs());
  }
  result.real_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - real_start).count();
  return result;
}

}  // namespace dentmark::simulation
