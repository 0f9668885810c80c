// `dentmark-edge simulate`: the marking station's twin, end to end (design.md §7):
// the paper's Table I scenarios — positions A, B, C × yaw 0°, 10°, −15° — each runs the
// edge daemon (the `run` wiring) with simulated drivers: rendered cameras, simulated
// GPIO and the robot simulator over Modbus TCP; the host side sends the list over TCP.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "commands.h"
#include "dentmark/common/atomic_file.h"
#include "dentmark/common/log.h"
#include "dentmark/common/protocol/dml_file.h"
#include "dentmark/firmware/simulation/scan_truth.h"
#include "dentmark/firmware/simulation/station_sim.h"

namespace dentmark::edge {
namespace {

using simulation::ScanTruth;
using simulation::SimulatedDoor;

struct SimulateOptions {
  std::string defects_file;  // .dml from `dentmark detect` (default: the truth itself)
  std::string truth_file;    // truth.json from `dentmark synth scan`
  std::vector<std::string> scenarios{"all"};
  int width = 1280, height = 1024;
  double focal = 1740.0;
  double fps = 10.0;
  std::uint64_t seed = 1;
  std::string json_out;
  bool no_arm = false;
  bool truth_motion = false;
  std::string board_file;
  bool serve = false;
  int port = 0;
  std::vector<std::string> faults;
  bool next_job = false;
  double frame_time = 0.020;
  bool self_calibrate = false;
  std::string calibration_cache;
  int jobs = 0;  // scenarios run at once; 0: one per core, at most 4
};

struct Scenario {
  char position;
  double yaw_deg;
};

std::vector<Scenario> parse_scenarios(const std::vector<std::string>& names) {
  std::vector<Scenario> all;
  for (char p : {'A', 'B', 'C'})
    for (double y : {0.0, 10.0, -15.0}) all.push_back({p, y});
  if (names.size() == 1 && names[0] == "all") return all;
  std::vector<Scenario> out;
  for (const auto& n : names) {
    // "B10", "C-15", "A0"
    if (n.size() < 2 || (n[0] != 'A' && n[0] != 'B' && n[0] != 'C'))
      throw std::runtime_error("scenario '" + n + "': expected A|B|C followed by a yaw in degrees, e.g. B10");
    std::size_t used = 0;
    double yaw = 0.0;
    try {
      yaw = std::stod(n.substr(1), &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != n.size() - 1 || std::abs(yaw) > 30.0)
      throw std::runtime_error("scenario '" + n + "': yaw must be a number of degrees within ±30");
    out.push_back({n[0], yaw});
  }
  return out;
}

void print_table(const std::vector<simulation::ScenarioResult>& results) {
  std::printf("\nMarking error per axis in the robot base, mm (paper Table I: 7-16 mm)\n");
  std::printf("%-14s", "scenario");
  for (const auto& r : results)
    std::printf(" %c%+4.0f°", r.options.position, r.options.yaw * 180 / std::numbers::pi);
  std::printf("\n");
  const char* names[3] = {"|e_x| mean", "|e_y| mean", "|e_z| mean"};
  for (int a = 0; a < 3; ++a) {
    std::printf("%-14s", names[a]);
    for (const auto& r : results) std::printf(" %6.2f", r.mean_abs(a) * 1e3);
    std::printf("\n");
  }
  std::printf("%-14s", "worst |e|");
  for (const auto& r : results) std::printf(" %6.2f", r.max_abs.maxCoeff() * 1e3);
  std::printf("\n%-14s", "marked/sent");
  for (const auto& r : results) std::printf(" %3d/%-2d", r.marked, r.defects_sent);
  std::printf("\n");
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  double worst = 0.0;
  int n = 0;
  for (const auto& r : results)
    for (const auto& e : r.errors)
      mean += e.error_base.cwiseAbs(), worst = std::max(worst, e.error_base.cwiseAbs().maxCoeff()), ++n;
  if (n > 0) mean /= n;
  std::printf("\nover %d marks: mean |e_x| %.2f, |e_y| %.2f, |e_z| %.2f mm; worst axis error %.2f mm\n", n,
              mean.x() * 1e3, mean.y() * 1e3, mean.z() * 1e3, worst * 1e3);
  if (!results.empty()) {
    const auto& r = results.front();
    std::printf("calibration (%s): T_base_camL off the truth by %.3f mm, %.3f mrad; T_camL_sls by",
                r.self_calibrated ? "self-calibrated" : "drawn errors", r.robot_calibration_error * 1e3,
                r.robot_calibration_rotation * 1e3);
    for (const auto& x : results)
      std::printf(" %.3f mm/%.3f mrad", x.scanner_calibration_error * 1e3,
                  x.scanner_calibration_rotation * 1e3);
    std::printf("\n");
  }
  for (const auto& r : results)
    if (r.fault_time >= 0.0)
      std::printf(
          "fault at t = %.3f s (%c%+.0f): valve closed after %.1f ms, robot still after %.1f ms, "
          "every defect reported after %.1f ms\n",
          r.fault_time, r.options.position, r.options.yaw * 180.0 / std::numbers::pi,
          r.valve_closed_after * 1e3, r.robot_still_after * 1e3, r.reported_after * 1e3);
  for (const auto& r : results)
    if (r.next_job)
      std::printf("next job (%c%+.0f, scanned at t = %.3f s): marked/sent %d/%d, worst axis error %.2f mm\n",
                  r.options.position, r.options.yaw * 180.0 / std::numbers::pi, r.next_job->t_scan,
                  r.next_job->marked, r.next_job->defects_sent, r.next_job->max_abs.maxCoeff() * 1e3);
}

nlohmann::json to_json(const simulation::ScenarioResult& r) {
  nlohmann::json marks = nlohmann::json::array();
  for (const auto& e : r.errors)
    marks.push_back({{"defect_id", e.defect_id},
                     {"truth_index", e.truth_index},
                     {"t_spray", e.t_spray},
                     {"error_base", {e.error_base.x(), e.error_base.y(), e.error_base.z()}}});
  nlohmann::json next_job = nullptr;
  if (r.next_job) {
    const auto& n = *r.next_job;
    nlohmann::json next_marks = nlohmann::json::array();
    for (const auto& e : n.errors)
      next_marks.push_back({{"defect_id", e.defect_id},
                            {"truth_index", e.truth_index},
                            {"t_spray", e.t_spray},
                            {"error_base", {e.error_base.x(), e.error_base.y(), e.error_base.z()}}});
    next_job = {{"t_scan", n.t_scan},
                {"defects_sent", n.defects_sent},
                {"marked", n.marked},
                {"unmatched_marks", n.unmatched_marks},
                {"valve_pulses", n.valve_pulses},
                {"mean_abs_error", {n.mean_abs.x(), n.mean_abs.y(), n.mean_abs.z()}},
                {"max_abs_error", {n.max_abs.x(), n.max_abs.y(), n.max_abs.z()}},
                {"marks", next_marks}};
  }
  return {{"position", std::string(1, r.options.position)},
          {"yaw", r.options.yaw},
          {"defects_sent", r.defects_sent},
          {"marked", r.marked},
          {"unmatched_marks", r.unmatched_marks},
          {"mean_abs_error", {r.mean_abs.x(), r.mean_abs.y(), r.mean_abs.z()}},
          {"max_abs_error", {r.max_abs.x(), r.max_abs.y(), r.max_abs.z()}},
          {"frames_tracked", r.frames_tracked},
          {"frames_failed", r.frames_failed},
          {"frames_offered", r.frames_offered},
          {"sim_seconds", r.sim_seconds},
          {"real_seconds", r.real_seconds},
          {"self_calibrated", r.self_calibrated},
          {"robot_calibration_error", r.robot_calibration_error},
          {"robot_calibration_rotation", r.robot_calibration_rotation},
          {"scanner_calibration_error", r.scanner_calibration_error},
          {"scanner_calibration_rotation", r.scanner_calibration_rotation},
          {"fault_time", r.fault_time},
          {"valve_closed_after", r.valve_closed_after},
          {"robot_still_after", r.robot_still_after},
          {"reported_after", r.reported_after},
          {"tracking_lost_after", r.detected_after},
          {"next_job", next_job},
          {"marks", marks}};
}

// The least share of the camera frames that must reach the station for the run to
// count. Rendering and tracking hold the twin's clock, so the cameras keep their rate
// on any machine; fewer pairs mean the cameras failed, and the marks are not the
// station's.
constexpr double kMinFramesTaken = 0.8;

// $XDG_CACHE_HOME/dentmark/twin-calibration, else ~/.cache/..., else the temporary folder.
std::filesystem::path default_calibration_cache() {
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x != nullptr && *x != '\0')
    return std::filesystem::path(x) / "dentmark" / "twin-calibration";
  if (const char* h = std::getenv("HOME"); h != nullptr && *h != '\0')
    return std::filesystem::path(h) / ".cache" / "dentmark" / "twin-calibration";
  return std::filesystem::temp_directory_path() / "dentmark-twin-calibration";
}

// Scenarios run side by side: each is a lock-step twin of its own, so the figures do
// not depend on how many share the machine.
int scenario_workers(const SimulateOptions& opt, std::size_t scenarios) {
  int n = opt.jobs > 0 ? opt.jobs : std::clamp(static_cast<int>(std::thread::hardware_concurrency()), 1, 4);
  if (opt.serve) n = 1;  // one port
  return std::clamp(n, 1, static_cast<int>(std::max<std::size_t>(1, scenarios)));
}

std::string scenario_name(const simulation::ScenarioOptions& s) {
  char name[32];
  std::snprintf(name, sizeof name, "%c%+.0f", s.position, s.yaw * 180.0 / std::numbers::pi);
  return name;
}

std::vector<simulation::ScenarioResult> run_scenarios(const std::vector<simulation::ScenarioOptions>& runs,
                                                      const simulation::SimulationOptions& sim,
                                                      const protocol::DefectList& list,
                                                      const ScanTruth& truth, int workers) {
  std::vector<std::optional<simulation::ScenarioResult>> done(runs.size());
  std::vector<std::string> failed(runs.size());
  std::atomic<std::size_t> next{0};
  const auto work = [&] {
    for (std::size_t i = next++; i < runs.size(); i = next++) {
      try {
        done[i] = simulation::run_scenario(runs[i], sim, list, truth);
      } catch (const std::exception& e) {
        failed[i] = e.what();
        continue;
      }
      const auto& r = *done[i];
      log::info("scenario " + scenario_name(runs[i]) + ": marked " + std::to_string(r.marked) + "/" +
                std::to_string(r.defects_sent) + ", frames tracked " + std::to_string(r.frames_tracked) +
                " (failed " + std::to_string(r.frames_failed) + "), " + std::to_string(r.real_seconds) +
                " s real for " + std::to_string(r.sim_seconds) + " s simulated");
    }
  };
  std::vector<std::thread> pool;
  for (int w = 1; w < workers; ++w) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
  std::vector<simulation::ScenarioResult> results;
  for (std::size_t i = 0; i < runs.size(); ++i) {
    if (!done[i]) throw std::runtime_error("scenario " + scenario_name(runs[i]) + ": " + failed[i]);
    results.push_back(std::move(*done[i]));
  }
  return results;
}

int run_simulate(const SimulateOptions& opt) {
  ScanTruth truth;
  protocol::DefectList list;
  std::vector<Scenario> scenarios;
  std::vector<simulation::Fault> faults;
  try {
    scenarios = parse_scenarios(opt.scenarios);
    if (opt.truth_file.empty() != opt.defects_file.empty())
      throw std::runtime_error("--defects and --truth go together (neither: built-in door)");
    for (const auto& f : opt.faults) faults.push_back(simulation::parse_fault(f));
    if (opt.serve && opt.next_job)
      throw std::runtime_error("--next-job runs the host side inside: not with --serve");
    if (opt.serve && (opt.defects_file.empty() || scenarios.size() != 1))
      throw std::runtime_error(
          "--serve needs --defects/--truth (the list the host sends) and one --scenario");
    if (opt.truth_file.empty()) {
      SimulatedDoor door = simulation::simulated_door(opt.seed, 6, 0.004);
      truth = std::move(door.truth);
      list = std::move(door.list);
    } else {
      truth = simulation::read_scan_truth(opt.truth_file);
      list = protocol::read_dml(opt.defects_file);
    }
  } catch (const std::exception& e) {
    log::error(e.what());
    return 2;
  }
  log::info("simulating " + std::to_string(scenarios.size()) + " scenario(s), " +
            std::to_string(list.defects.size()) + " defects sent, " + std::to_string(truth.defects.size()) +
            " true defects");
  simulation::SimulationOptions sim;
  sim.arm_occludes = !opt.no_arm;
  sim.truth_motion = opt.truth_motion;
  sim.board_file = opt.board_file;
  sim.serve = opt.serve;
  sim.faults = faults;
  sim.next_job = opt.next_job;
  sim.frame_processing_time = opt.frame_time;
  sim.serve_port = opt.port;
  if (opt.self_calibrate)
    sim.self_calibration_cache =
        opt.calibration_cache.empty() ? default_calibration_cache().string() : opt.calibration_cache;
  std::vector<simulation::ScenarioOptions> runs;
  for (const Scenario& s : scenarios) {
    simulation::ScenarioOptions so;
    so.position = s.position;
    so.yaw = s.yaw_deg * std::numbers::pi / 180.0;
    so.width = opt.width;
    so.height = opt.height;
    so.focal_px = opt.focal;
    so.fps = opt.fps;
    so.seed = opt.seed;
    runs.push_back(so);
  }
  std::vector<simulation::ScenarioResult> results;
  try {
    results = run_scenarios(runs, sim, list, truth, scenario_workers(opt, runs.size()));
  } catch (const std::exception& e) {
    log::error(e.what());
    return 1;
  }
  print_table(results);
  // Where the cameras delivered a fraction of their frames, the table is not the station's.
  double taken = 0.0, offered = 0.0;
  for (const auto& r : results)
    taken += static_cast<double>(r.frames_tracked + r.frames_failed),
        offered += static_cast<double>(r.frames_offered);
  if (offered > 0.0 && taken < kMinFramesTaken * offered) {
    char why[320];
    std::snprintf(why, sizeof why,
                  "the cameras delivered %.0f of their %.0f stereo pairs: the marks above are "
                  "not the station's",
                  taken, offered);
    log::error(why);
    return 3;
  }
  if (!opt.json_out.empty()) {
    nlohmann::json j = {{"schema", "dentmark.station-sim/1"}, {"scenarios", nlohmann::json::array()}};
    for (const auto& r : results) j["scenarios"].push_back(to_json(r));
    try {
      files::write_atomically(opt.json_out, j.dump(1) + "\n");
    } catch (const files::FileError& e) {
      log::error(e.what());
      return 1;
    }
  }
  return 0;
}

}  // namespace

void register_simulate(CLI::App& app) {
  auto opt = std::make_shared<SimulateOptions>();
  CLI::App* cmd = app.add_subcommand(
      "simulate", "Run the simulated marking station (paper Table I scenarios) and print the marking errors");
  cmd->add_option("--defects", opt->defects_file, "Defect list (.dml) from `dentmark detect`");
  cmd->add_option("--truth", opt->truth_file, "Scan truth (.json) from `dentmark synth scan`");
  cmd->add_option("--scenario", opt->scenarios, "all, or scenarios like A0 B10 C-15")->capture_default_str();
  cmd->add_option("--jobs", opt->jobs,
                  "Scenarios run at once (0: one per core, at most 4); the figures do not depend on it")
      ->capture_default_str()
      ->check(CLI::Range(0, 64));
  cmd->add_option("--width", opt->width, "Camera width, px")
      ->capture_default_str()
      ->check(CLI::Range(160, 4096));
  cmd->add_option("--height", opt->height, "Camera height, px")
      ->capture_default_str()
      ->check(CLI::Range(120, 4096));
  cmd->add_option("--focal", opt->focal, "Focal length, px")
      ->capture_default_str()
      ->check(CLI::Range(100.0, 20000.0));
  cmd->add_option("--fps", opt->fps, "Camera frame rate, Hz")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 120.0));
  cmd->add_option("--seed", opt->seed, "Seed (calibration errors, noise, built-in door)")
      ->capture_default_str();
  cmd->add_flag("--no-arm", opt->no_arm, "Do not render the robot arm in the cameras' view");
  cmd->add_flag("--truth-motion", opt->truth_motion,
                "Use the true panel motion instead of the tracker (diagnostics)");
  cmd->add_option("--json", opt->json_out, "Write per-mark results as JSON");
  cmd->add_option("--board", opt->board_file, "The twin's board file (default: boards/sim/twin/board.yaml)");
  cmd->add_option(
      "--fault", opt->faults,
      "Inject a fault KIND@SECONDS after marking starts: estop, robot-link, robot-blip, robot-fault, "
      "camera, tracking, daemon-kill (SIGKILL, restarted after 1 s) (repeatable)");
  cmd->add_option("--frame-time", opt->frame_time,
                  "Seconds of simulated time the target board takes to track one stereo frame")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  cmd->add_flag("--next-job", opt->next_job,
                "After the job: clear the faults, scan the door again where it then is and send it as the "
                "next job (scored like the first)");
  cmd->add_flag("--serve", opt->serve,
                "Wait for an outside host to send the list (dentmark send --wait) instead of sending it");
  cmd->add_option("--port", opt->port, "With --serve: the link port (0: any free port, logged)")
      ->check(CLI::Range(0, 65535));
  cmd->add_flag("--self-calibrate", opt->self_calibrate,
                "Commission the twin by running the calibrations (stereo, robot live, scanner) on its own "
                "rendered views instead of drawing calibration errors; cached (--calibration-cache)");
  cmd->add_option(
      "--calibration-cache", opt->calibration_cache,
      "Folder of the self-calibration's cache (default $XDG_CACHE_HOME/dentmark/twin-calibration)");
  cmd->callback([opt] { exit_code() = run_simulate(*opt); });
}

}  // namespace dentmark::edge
