// System test of the station's twin: the real station code (planner, job runner,
// Modbus robot client) against the robot simulator on loopback, scored against the
// simulator's truth of where each defect was when the sprayer fired.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <numbers>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "dentmark/firmware/simulation/scan_truth.h"
#include "dentmark/firmware/simulation/station_sim.h"

// The twin's threads run on a scaled real-time clock; an emulated CPU (qemu-user) is
// too slow and too uneven for those timings to mean anything.
#ifdef DENTMARK_UNDER_EMULATION
#define SKIP_UNDER_EMULATION() GTEST_SKIP() << "real-time-scaled system test; runs natively"
#else
#define SKIP_UNDER_EMULATION() (void)0
#endif

namespace dentmark::simulation {
namespace {

// The longest a moving tool takes to brake to rest (board limits: 0.25 m/s at 1 m/s²),
// with a poll period to spare.
constexpr double kBrakingTime = 0.30;

SimulatedDoor door(std::uint64_t seed, int defects) {
  return simulated_door(seed, defects);
}

TEST(StationSim, MarksMovingPanelWithinTwoMillimetresGivenTrueMotion) {
  SKIP_UNDER_EMULATION();
  const SimulatedDoor d = door(3, 4);
  for (auto [pos, yaw_deg] : {std::pair{'B', 10.0}, std::pair{'C', -15.0}}) {
    ScenarioOptions s;
    s.position = pos;
    s.yaw = yaw_deg * std::numbers::pi / 180.0;
    SimulationOptions sim;
    sim.truth_motion = true;
    const ScenarioResult r = run_scenario(s, sim, d.list, d.truth);
    EXPECT_EQ(r.marked, 4) << pos << yaw_deg;
    EXPECT_EQ(r.valve_pulses, 4) << "one valve pulse per mark, through the safety supervisor";
    ASSERT_EQ(r.errors.size(), 4u);
    EXPECT_EQ(r.unmatched_marks, 0);
    // Errors come only from the simulated calibration (0.3 mm, 0.2 mrad) and robot
    // accuracy (0.3 mm): the chain itself must add nothing visible.
    EXPECT_LT(r.mean_abs.maxCoeff(), 2e-3) << pos << yaw_deg;
    EXPECT_LT(r.max_abs.maxCoeff(), 4e-3) << pos << yaw_deg;
    // The panel really moved between scan and marks: 0.27 m per position.
    EXPECT_GT(r.errors.front().t_spray, (pos - 'A') * 0.27 / 0.014);
  }
}

TEST(StationSim, ErrorsReflectACalibrationOffset) {
  SKIP_UNDER_EMULATION();
  // With perfect calibrations and robot, the twin must mark almost exactly; a 5 mm
  // calibration error must show up as ~5 mm: the scoring can fail.
  const SimulatedDoor d = door(5, 3);
  ScenarioOptions s;
  s.position = 'A';
  s.calibration_translation = 0.0;
  s.calibration_rotation = 0.0;
  s.robot_accuracy = 0.0;
  s.robot_repeatability = 0.0;
  SimulationOptions sim;
  sim.truth_motion = true;
  const ScenarioResult exact = run_scenario(s, sim, d.list, d.truth);
  ASSERT_EQ(exact.errors.size(), 3u);
  // On the lock-step clock no latency of this machine shows: what remains is the
  // planner's own approximation.
  EXPECT_LT(exact.max_abs.maxCoeff(), 0.5e-3);

  s.calibration_translation = 5e-3;
  const ScenarioResult off = run_scenario(s, sim, d.list, d.truth);
  ASSERT_EQ(off.errors.size(), 3u);
  EXPECT_GT(off.errors.front().error_base.norm(), 3e-3);
}

TEST(StationSim, EstopStopsTheJobWithTheValveClosed) {
  SKIP_UNDER_EMULATION();
  const SimulatedDoor d = door(4, 5);
  ScenarioOptions s;
  s.position = 'A';
  SimulationOptions sim;
  sim.truth_motion = true;
  sim.faults = {{FaultKind::kEstop, 3.0}};  // while marking the first or second defect
  const ScenarioResult r = run_scenario(s, sim, d.list, d.truth);
  EXPECT_LT(r.marked, 5);
  EXPECT_FALSE(r.valve_open_at_end);
  int estopped = 0;
  for (const auto& m : r.report.marks)
    if (m.outcome == protocol::MarkOutcome::kFailed && m.reason == protocol::MarkReason::kEmergencyStop)
      ++estopped;
  EXPECT_GE(estopped, 1);
  EXPECT_EQ(static_cast<int>(r.report.marks.size()), 5);
  // No spray after the e-stop.
  for (const auto& e : r.errors) EXPECT_LT(e.t_spray, 3.0 + 0.05);  // position A: marking starts at 0
}

// What every fault must leave behind: the valve closed, every defect reported once
// with an outcome, no defect sprayed twice, nothing sprayed after the fault took hold.
void expect_safe_end(const ScenarioResult& r, const protocol::DefectList& list, const std::string& what) {
  SCOPED_TRACE(what);
  EXPECT_FALSE(r.valve_open_at_end);
  ASSERT_EQ(r.report.marks.size(), list.defects.size()) << "every defect is reported";
  std::set<std::uint32_t> ids;
  for (const auto& m : r.report.marks) EXPECT_TRUE(ids.insert(m.defect_id).second) << "reported twice";
  // One valve pulse per mark; at most one more, for the defect whose spray the fault cut
  // short (reported failed: it may carry paint, and is never sprayed again).
  EXPECT_GE(r.valve_pulses, r.marked);
  EXPECT_LE(r.valve_pulses, r.marked + 1);
  std::set<std::uint32_t> sprayed;
  for (const auto& e : r.errors) EXPECT_TRUE(sprayed.insert(e.defect_id).second) << "sprayed twice";
}

// The next job after a fault (the faults cleared where they clear): accepted, every
// defect marked once, the marks as good as a job without a fault.
void expect_next_job_marked(const ScenarioResult& r, const protocol::DefectList& list, double max_error,
                            const std::string& what) {
  SCOPED_TRACE(what + ", next job");
  ASSERT_TRUE(r.next_job.has_value()) << "the daemon accepts the next job";
  const NextJobResult& n = *r.next_job;
  EXPECT_EQ(n.report.job_id, list.job_id + 1);
  ASSERT_EQ(n.report.marks.size(), list.defects.size()) << "every defect of the next job is reported";
  for (const auto& m : n.report.marks) EXPECT_EQ(m.outcome, protocol::MarkOutcome::kMarked) << m.defect_id;
  EXPECT_EQ(n.marked, static_cast<int>(list.defects.size()));
  EXPECT_EQ(n.valve_pulses, n.marked) << "one valve pulse per mark";
  EXPECT_FALSE(n.valve_open_at_end);
  EXPECT_EQ(n.unmatched_marks, 0);
  ASSERT_EQ(n.errors.size(), list.defects.size());
  std::set<std::uint32_t> sprayed;
  for (const auto& e : n.errors) {
    EXPECT_TRUE(sprayed.insert(e.defect_id).second) << "sprayed twice";
    EXPECT_GT(e.t_spray, n.t_scan) << "sprayed after the second scan";
  }
  // Against the simulator's truth of where each defect was at its spray.
  EXPECT_LT(n.max_abs.maxCoeff(), max_error);
}

// The three instants of a job at which each fault is injected, from the same job run
// without a fault (marking at A starts at t = 0): before the first move, moving towards
// the second defect (0.8 s before its spray), and half-way through the third spray.
enum class Instant { kBefore, kMoving, kSpraying };
struct FaultInstant {
  Instant instant;
  double after;
};
std::vector<FaultInstant> instants_of(const ScenarioResult& clean) {
  constexpr double kPulse = 0.15;  // s, the planner's spray_duration
  std::vector<double> sprays;
  for (const auto& e : clean.errors) sprays.push_back(e.t_spray);
  std::sort(sprays.begin(), sprays.end());
  if (sprays.size() < 3) return {};
  return {{Instant::kBefore, 0.0},
          {Instant::kMoving, sprays[1] - 0.8},
          {Instant::kSpraying, sprays[2] + kPulse / 2}};
}
const char* to_string(Instant i) {
  return i == Instant::kBefore ? "before marks" : i == Instant::kMoving ? "moving" : "spraying";
}

// How the station sees a lost panel: dead cameras at the next frame, whose grab fails
// (the job then goes safe at once); a panel out of view once the next frame is tracked
// (the board's modelled 20 ms per frame), after which a spray that began on a
// still-valid estimate ends its pulse and the tool retracts. The bounds below follow
// from that.
constexpr double kFramePeriod = 0.1;       // s (10 fps)
constexpr double kFrameProcessing = 0.02;  // s, SimulationOptions::frame_processing_time
constexpr double kPulse = 0.15;            // s
constexpr double kRetract = 0.5;           // s, 60 mm back at 0.25 m/s, 1 m/s²
constexpr double kTrackingTimeout = 5.0;   // s, JobConfig::tracking_timeout
constexpr double kRobotWatchdog = 0.5;     // s, the twin robot's heartbeat timeout
constexpr double kRestartAfter = 1.0;      // s, the unit's RestartSec

// Every defect not marked names the fault that stopped it.
void expect_reasons_name_the_fault(const ScenarioResult& r, FaultKind kind, const std::string& what) {
  const std::set<protocol::MarkReason> expected =
      kind == FaultKind::kEstop        ? std::set{protocol::MarkReason::kEmergencyStop}
      : kind == FaultKind::kDaemonKill ? std::set{protocol::MarkReason::kAborted}
      : kind == FaultKind::kCamera || kind == FaultKind::kTrackingLost
          ? std::set{protocol::MarkReason::kTrackingLost}
          : std::set{protocol::MarkReason::kRobotFault, protocol::MarkReason::kTimeout};
  for (const auto& m : r.report.marks)
    if (m.outcome != protocol::MarkOutcome::kMarked) {
      EXPECT_TRUE(expected.count(m.reason)) << what << ": defect " << m.defect_id << " names the fault";
    }
}

// How soon after the injection (simulated time: the station's reaction by design) the
// valve is closed, the tool still and every defect reported, and that nothing is sprayed
// once the fault could be seen.
void expect_time_to_safe(const ScenarioResult& r, FaultKind kind, double t_fault, const std::string& what) {
  const auto no_spray_after = [&](double t) {
    for (const auto& e : r.errors) EXPECT_LT(e.t_spray, t) << what << ": spray too late";
  };
  switch (kind) {
    case FaultKind::kDaemonKill:
      // The kill ends the valve line's request: the valve closes at once. The robot
      // hears no heartbeat and its watchdog stops it; the restarted daemon reports
      // every defect not marked before the kill failed / aborted.
      no_spray_after(t_fault);
      EXPECT_LE(r.valve_closed_after, 0.0) << what;
      EXPECT_LE(r.robot_still_after, kRobotWatchdog + kBrakingTime) << what;
      EXPECT_GE(r.reported_after, kRestartAfter - 1e-3) << what << ": only the restarted daemon reports";
      EXPECT_LE(r.reported_after, kRestartAfter + 0.05) << what;
      return;
    case FaultKind::kCamera:
      // Dead cameras show at the next frame (its grab fails); the job goes safe at the
      // next interlock check, cutting a spray short: valve closed, robot stopped and
      // every defect reported within 50 ms of that.
      ASSERT_GE(r.detected_after, 0.0) << what << ": a defect is reported tracking_lost";
      EXPECT_LE(r.detected_after, kFramePeriod + 0.05) << what;
      no_spray_after(t_fault + kFramePeriod);
      EXPECT_LE(r.valve_closed_after, r.detected_after + 0.05) << what;
      EXPECT_LE(r.robot_still_after, r.detected_after + kBrakingTime + 0.05) << what;
      EXPECT_LE(r.reported_after, r.detected_after + 0.05) << what;
      return;
    case FaultKind::kTrackingLost: {
      // A panel out of view shows once the next frame is tracked; a tool moving
      // towards the panel is stopped at the next poll, and no spray starts after that.
      const double seen = kFramePeriod + kFrameProcessing;
      ASSERT_GE(r.detected_after, 0.0) << what << ": a defect is reported tracking_lost";
      no_spray_after(t_fault + seen + 0.01);
      EXPECT_LE(r.valve_closed_after, seen + kPulse + 0.05) << what;
      EXPECT_LE(r.robot_still_after, seen + std::max(kBrakingTime, kPulse + kRetract) + 0.05) << what;
      EXPECT_LE(r.reported_after, seen + kPulse + kRetract + kTrackingTimeout + 0.05) << what;
      return;
    }
    default:
      // The e-stop closes the valve on its edge; a robot fault or a dead link is seen
      // at the next robot exchange (poll period) and the valve closes then. A dead link
      // leaves the robot to its own watchdog and braking.
      no_spray_after(t_fault + 0.05);
      EXPECT_LE(r.valve_closed_after, kind == FaultKind::kEstop ? 0.010 : 0.050) << what;
      EXPECT_LE(r.robot_still_after,
                kind == FaultKind::kRobotLink ? kRobotWatchdog + kBrakingTime : kBrakingTime)
          << what;
      EXPECT_LE(r.reported_after, 0.050) << what;
  }
}

// Every fault kind at three instants of a job at A (the built-in door of seed 6, 4
// defects), then the next job: the robot's faults on the true motion (fast), the
// cameras' on the real tracker with rendered frames at the paper's image size.
void every_fault_ends_safe(bool cameras) {
  const SimulatedDoor d = door(6, 4);
  std::printf("%-12s %-13s %7s %9s %9s %9s %9s   next job\n", "fault", "instant", "at", "gave up", "valve",
              "still", "reported");
  ScenarioOptions s;
  s.position = 'A';
  if (cameras) s.width = 640, s.height = 512, s.focal_px = 870.0;
  SimulationOptions clean_sim;
  clean_sim.truth_motion = !cameras;
  const ScenarioResult clean = run_scenario(s, clean_sim, d.list, d.truth);
  ASSERT_EQ(clean.marked, 4);
  const std::vector<FaultInstant> instants = instants_of(clean);
  ASSERT_EQ(instants.size(), 3u);
  const auto kinds = cameras
                         ? std::vector{FaultKind::kCamera, FaultKind::kTrackingLost, FaultKind::kDaemonKill}
                         : std::vector{FaultKind::kEstop, FaultKind::kRobotLink, FaultKind::kRobotFault,
                                       FaultKind::kRobotLinkBlip, FaultKind::kDaemonKill};
  for (FaultKind kind : kinds)
    for (const FaultInstant& at : instants) {
      SimulationOptions sim = clean_sim;
      sim.faults = {{kind, at.after}};
      sim.next_job = true;
      const ScenarioResult r = run_scenario(s, sim, d.list, d.truth);
      const std::string what = std::string(to_string(kind)) + "@" + std::to_string(at.after);
      expect_safe_end(r, d.list, what);
      expect_next_job_marked(r, d.list, cameras ? 2.5e-3 : 2e-3, what);
      // The instant is the one meant.
      EXPECT_EQ(r.valve_open_at_fault, at.instant == Instant::kSpraying) << what;
      EXPECT_EQ(r.robot_speed_at_fault > 0.0, at.instant == Instant::kMoving) << what;
      for (const auto& m : r.report.marks)
        if (m.outcome != protocol::MarkOutcome::kMarked) {
          EXPECT_NE(m.reason, protocol::MarkReason::kNone)
              << what << ": a defect not marked names its reason";
        }
      std::printf("%-12s %-13s %5.2f s %6.0f ms %6.0f ms %6.0f ms %6.0f ms   %d/%zu marked, worst %.2f mm\n",
                  to_string(kind), to_string(at.instant), at.after, r.detected_after * 1e3,
                  r.valve_closed_after * 1e3, r.robot_still_after * 1e3, r.reported_after * 1e3,
                  r.next_job ? r.next_job->marked : -1, d.list.defects.size(),
                  r.next_job ? r.next_job->max_abs.maxCoeff() * 1e3 : -1.0);
      if (kind == FaultKind::kRobotLinkBlip) {
        // A dropped request: the Modbus client reconnects and the job goes on.
        EXPECT_EQ(r.marked, 4) << what;
        continue;
      }
      EXPECT_LT(r.marked, 4) << what;
      expect_reasons_name_the_fault(r, kind, what);
      expect_time_to_safe(r, kind, at.after, what);
    }
}

TEST(StationSim, EveryFaultEndsSafeOnTheTrueMotion) {
  SKIP_UNDER_EMULATION();
  every_fault_ends_safe(false);
}

TEST(StationSim, EveryFaultEndsSafeWithTheTracker) {
  SKIP_UNDER_EMULATION();
  every_fault_ends_safe(true);
}

TEST(StationSim, SameSeedSameMarksToTheBitUnderLoad) {
  SKIP_UNDER_EMULATION();
  // The real tracker on rendered frames: the lock-step clock must give the same marks,
  // spray times and errors to the last bit, with the machine idle or busy.
  const SimulatedDoor d = door(9, 3);
  ScenarioOptions s;
  s.position = 'A';
  s.width = 640, s.height = 512, s.focal_px = 870.0;
  const SimulationOptions sim;
  const ScenarioResult quiet = run_scenario(s, sim, d.list, d.truth);
  ASSERT_EQ(quiet.marked, 3);
  std::atomic<bool> busy{true};
  std::vector<std::thread> load;
  for (int i = 0; i < 3; ++i)
    load.emplace_back([&] {
      volatile double x = 0.0;
      while (busy) x = x + 1.0;
    });
  const ScenarioResult loaded = run_scenario(s, sim, d.list, d.truth);
  busy = false;
  for (auto& t : load) t.join();
  ASSERT_EQ(loaded.errors.size(), quiet.errors.size());
  for (std::size_t i = 0; i < quiet.errors.size(); ++i) {
    EXPECT_EQ(loaded.errors[i].defect_id, quiet.errors[i].defect_id);
    EXPECT_EQ(loaded.errors[i].t_spray, quiet.errors[i].t_spray);
    EXPECT_EQ(loaded.errors[i].error_base, quiet.errors[i].error_base);
  }
  ASSERT_EQ(loaded.report.marks.size(), quiet.report.marks.size());
  for (std::size_t i = 0; i < quiet.report.marks.size(); ++i) {
    EXPECT_EQ(loaded.report.marks[i].time, quiet.report.marks[i].time);
    EXPECT_EQ(loaded.report.marks[i].outcome, quiet.report.marks[i].outcome);
  }
  EXPECT_EQ(loaded.sim_seconds, quiet.sim_seconds);
  EXPECT_EQ(loaded.frames_tracked, quiet.frames_tracked);
}

}  // namespace
}  // namespace dentmark::simulation
