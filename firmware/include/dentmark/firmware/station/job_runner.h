#pragma once
// Runs one marking job (design.md §4, daemon): for the panel of a DefectList it plans
// the marks on the moving panel, drives the robot approach → point → spray → retract
// for each, and reports what it marked, where and when.
//
// Safety: the e-stop is read before every step and while waiting; on e-stop, robot
// fault, lost tracking or any exception the valve is closed, the robot is aborted and
// the remaining defects are reported with the reason. Every wait has a timeout.

#include <atomic>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "dentmark/common/clock/clock.h"
#include "dentmark/common/protocol/messages.h"
#include "dentmark/firmware/hal/robot/robot.h"
#include "dentmark/firmware/plan/marking_plan.h"
#include "dentmark/firmware/station/motion_source.h"
#include "dentmark/firmware/station/tracking_trust.h"

namespace dentmark::station {

// The station's safety I/O apart from the robot (GPIO on the edge box).
class SafetyIo {
 public:
  virtual ~SafetyIo() = default;
  virtual bool estop_active() = 0;
  // The e-stop input as it reads now: a new job is refused while it is pressed; a
  // latch left by an earlier e-stop is cleared by arm() once it is released.
  virtual bool estop_pressed() { return estop_active(); }
  // Clears latched safe states at the start of a job (the operator's go-ahead);
  // false when that is not allowed (e-stop pressed).
  virtual bool arm() { return !estop_active(); }
  // Called every turn of the control loop (software watchdog).
  virtual void kick() {}
  // Opens the sprayer valve for 'duration' seconds of clock time, then closes it;
  // false when the valve was refused (latched safe). 'watch' runs every turn of the
  // control loop while the valve is open; when it throws, the valve closes at once and
  // the exception goes on.
  virtual bool spray(double duration, const std::function<void()>& watch) = 0;
  // Closes the valve (idempotent, never throws).
  virtual void valve_off() noexcept = 0;
};

// Told of every step of a job that must outlive a crash (the daemon's journal) or
// reach the host as it happens. Both are called on the job's thread.
class JobEvents {
 public:
  virtual ~JobEvents() = default;
  // Just before the valve opens for a defect. Once this returns the defect counts as
  // possibly sprayed: it is never sprayed again, even after a restart.
  virtual void spraying(std::uint32_t /*defect_id*/) {}
  // A defect's outcome, as soon as it is decided.
  virtual void reported(const protocol::Mark& /*mark*/) {}
};

struct JobConfig {
  plan::PlannerConfig planner;
  double approach_distance = 0.04;     // m back along the tool axis before the final approach
  double retract_distance = 0.06;      // m back along the tool axis after spraying
  double correction_tolerance = 4e-4;  // m: re-aim before spraying when the target moved more
  int max_corrections = 3;
  TrackingTrust trust;               // the estimates steered by (tracking_trust.h)
  double max_estimate_age = 0.5;     // s: tracking is lost once the newest trusted estimate is older
  double tracking_timeout = 5.0;     // s to wait for tracking before giving up on a defect
  double move_timeout_margin = 2.0;  // s allowed beyond the planned move time
  double poll_period = 0.01;         // s between status polls
  double robot_reset_timeout = 2.0;  // s for the robot to clear a stop latched while idle
  double epoch_offset = 0.0;         // s: clock time + epoch_offset = Unix time (for reports)
};

class JobRunner {
 public:
  JobRunner(hal::Robot& robot, SafetyIo& safety, MotionSource& motion, clock::Clock& clock, JobConfig config);

  // Marks the list's dent, bump and hole defects. t_scan is the scan's time on the
  // clock; the motion source must cover it. Never throws: failures are in the report,
  // and each outcome is also passed to 'events' as it is decided.
  protocol::MarkReport run(const protocol::DefectList& list, double t_scan, JobEvents* events = nullptr);

  protocol::EdgeState state() const { return state_.load(); }
  // Asks a running job to stop after the current step (thread-safe).
  void cancel() { cancelled_ = true; }

 private:
  struct Target;
  class Outcomes;
  // The list's markable defects as targets; the others are reported not markable.
  std::vector<Target> targets_of(const protocol::DefectList& list, Outcomes& outcomes) const;
  // Waits up to tracking_timeout for a usable estimate of a pair taken at 'since' or
  // later (with the robot live: interlocks checked and the heartbeat kept); true when
  // tracking is ok.
  bool wait_for_tracking(bool robot_live, double since = -std::numeric_limits<double>::infinity());
  // Connects, and clears a stop the station itself caused; throws on the robot's own fault.
  void start_robot();
  // Marks until nothing is left or tracking or reach give out (those get their reason);
  // faults propagate with the undecided targets still in 'remaining'.
  void mark_remaining(std::vector<Target>& remaining, const plan::MotionPredictor& since_scan,
                      Outcomes& outcomes);
  protocol::Mark mark_one(const Target& target, const plan::MotionPredictor& since_scan);
  // Towards the panel (tracked: a tracking loss during the move stops the tool and ends
  // the job, JobAbort tracking_lost) or away from it (untracked).
  enum class Toward { kPanel, kAway };
  hal::RobotStatus move_and_wait(const Transform& T_base_tool, double planned_time, Toward toward);
  // Robot::wait_done with the interlocks checked in every poll.
  // Throws JobAbort (robot fault) when the robot is faulted or stopped.
  static void check_robot(const hal::RobotStatus& s);
  hal::RobotStatus wait_robot(std::uint16_t sequence, double timeout, bool tracked = false);
  Transform predicted_tool_pose(const Target& target, const plan::MotionPredictor& since_scan,
                                double t) const;
  // Why the job cannot steer by the tracker now, or nullopt: no estimate yet, the
  // tracker lost the panel, or the newest trusted estimate older than max_estimate_age
  // (then why the newest is distrusted: poor or unsure estimates are coasted through).
  std::optional<std::string> tracking_problem();
  bool tracking_ok();
  void check_interlocks();

  hal::Robot& robot_;
  SafetyIo& safety_;
  MotionSource& motion_;
  clock::Clock& clock_;
  JobConfig config_;
  std::atomic<protocol::EdgeState> state_{protocol::EdgeState::kIdle};
  std::atomic<bool> cancelled_{false};
  Eigen::Vector3d tip_ = Eigen::Vector3d::Zero();
  JobEvents* events_ = nullptr;  // during run()
  // Frame time of the newest trusted estimate this job saw (-inf: none yet).
  double last_trusted_t_ = -std::numeric_limits<double>::infinity();
};

}  // namespace dentmark::station
