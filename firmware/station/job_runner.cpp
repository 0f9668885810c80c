#include "dentmark/firmware/station/job_runner.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "dentmark/common/log.h"
#include "dentmark/firmware/plan/marking_pose.h"

namespace dentmark::station {

using protocol::MarkOutcome;
using protocol::MarkReason;

namespace {

// Stops the whole job: every defect not yet marked is reported with 'reason'.
struct JobAbort {
  MarkReason reason;
  std::string why;
};

// Gives up on the current defect only.
struct SkipDefect {
  MarkReason reason;
  std::string why;
};

bool markable(protocol::DefectClass c) {
  return c == protocol::DefectClass::kDent || c == protocol::DefectClass::kBump ||
         c == protocol::DefectClass::kHole;
}

Transform backed_off(const Transform& T_base_tool, double distance) {
  // Back along the tool's own z axis (away from the surface).
  Transform t = T_base_tool;
  t.translation() -= distance * T_base_tool.linear().col(2);
  return t;
}

protocol::Mark unmarked(std::uint32_t id, MarkOutcome outcome, MarkReason reason) {
  protocol::Mark m;
  m.defect_id = id;
  m.outcome = outcome;
  m.reason = reason;
  return m;
}

}  // namespace

struct JobRunner::Target {
  std::uint32_t id = 0;
  Transform T_sls_v = Transform::Identity();
};

JobRunner::JobRunner(hal::Robot& robot, SafetyIo& safety, MotionSource& motion, clock::Clock& clock,
                     JobConfig config)
    : robot_(robot), safety_(safety), motion_(motion), clock_(clock), config_(std::move(config)) {}

Transform JobRunner::predicted_tool_pose(const Target& target, const plan::MotionPredictor& since_scan,
                                         double t) const {
  return plan::tool_pose_in_base(config_.planner.chain, since_scan(t), target.T_sls_v);
}

std::optional<std::string> JobRunner::tracking_problem() {
  const auto e = motion_.latest();
  if (!e) return "no estimate yet";
  // The tracker losing the panel is news at once; a poor or unsure estimate is no news,
  // coasted through until the trusted ones are too old.
  const auto doubt = config_.trust.doubt(*e);
  if (!e->ok) return doubt;
  if (!doubt) last_trusted_t_ = std::max(last_trusted_t_, e->t);
  const double age = clock_.now() - last_trusted_t_;
  if (age <= config_.max_estimate_age) return std::nullopt;
  const std::string too_old = std::isfinite(age)
                                  ? "the newest trusted estimate " + std::to_string(age) + " s old > " +
                                        std::to_string(config_.max_estimate_age) + " s"
                                  : "no trusted estimate in this job";
  return doubt ? *doubt + "; " + too_old : too_old;
}

bool JobRunner::tracking_ok() {
  return !tracking_problem();
}

void JobRunner::check_interlocks() {
  safety_.kick();
  if (safety_.estop_active()) throw JobAbort{MarkReason::kEmergencyStop, "e-stop active"};
  if (cancelled_) throw JobAbort{MarkReason::kAborted, "job cancelled"};
  if (const auto why = motion_.failure()) throw JobAbort{MarkReason::kTrackingLost, *why};
}

hal::RobotStatus JobRunner::move_and_wait(const Transform& T_base_tool, double planned_time, Toward toward) {
  if (!config_.planner.limits.contains(T_base_tool.translation()))
    throw SkipDefect{MarkReason::kOutOfReach, "pose outside the workspace"};
  const std::uint16_t seq = robot_.move_to(T_base_tool, config_.planner.limits.max_speed);
  const hal::RobotStatus s =
      wait_robot(seq, planned_time + config_.move_timeout_margin, toward == Toward::kPanel);
  tip_ = s.T_base_tool.translation();
  return s;
}

hal::RobotStatus JobRunner::wait_robot(std::uint16_t sequence, double timeout, bool tracked) {
  // The e-stop is honoured during a move or a spray, not only between them. Within a
  // job the robot is never stopped or faulted, whichever command it last took: a drive
  // fault between two commands must not be cleared by the next one. A refusal or stop
  // ends the job as a robot fault, a wait past 'timeout' as a timeout. A move towards
  // the panel aims where the tracker predicts it: with tracking lost (at a poll) the
  // tool is stopped there and then rather than sent on along a stale prediction.
  return robot_.wait_done(
      sequence, timeout, config_.poll_period, clock_, [this, tracked](const hal::RobotStatus& s) {
        check_interlocks();
        check_robot(s);
        if (!tracked) return;
        if (const auto why = tracking_problem())
          throw JobAbort{MarkReason::kTrackingLost, "tracking lost while approaching: " + *why};
      });
}

void JobRunner::check_robot(const hal::RobotStatus& s) {
  if (s.state == robot_link::State::kFault || s.state == robot_link::State::kStopped)
    throw JobAbort{MarkReason::kRobotFault, "robot " + std::string(robot_link::to_string(s.state)) + ": " +
                                                robot_link::fault_names(s.faults)};
}

protocol::Mark JobRunner::mark_one(const Target& target, const plan::MotionPredictor& since_scan) {
  const plan::RobotLimits& limits = config_.planner.limits;
  // Where the tool must be to meet the defect: t = now + move_time(tip → pose(t)),
  // solved by fixed-point iteration (the line is slow against the tool).
  const auto aim = [&](double back_off) {
    double t = clock_.now();
    Transform pose = backed_off(predicted_tool_pose(target, since_scan, t), back_off);
    for (int i = 0; i < 8; ++i) {
      t = clock_.now() + plan::move_time((pose.translation() - tip_).norm(), limits);
      pose = backed_off(predicted_tool_pose(target, since_scan, t), back_off);
    }
    return std::pair{pose, t - clock_.now()};
  };

  // Approach: stand off along the tool axis, then go in straight along it.
  const auto [approach, t_approach] = aim(config_.approach_distance);
  move_and_wait(approach, t_approach, Toward::kPanel);
  hal::RobotStatus at{};
  double residual = 0.0;
  for (int k = 0; k <= config_.max_corrections; ++k) {
    check_interlocks();
    if (const auto why = tracking_problem())
      throw SkipDefect{MarkReason::kTrackingLost, "tracking lost before spraying: " + *why};
    const auto [pose, t_move] = aim(0.0);
    at = move_and_wait(pose, t_move, Toward::kPanel);
    // The panel kept moving while the tool travelled: how far is the target now?
    residual = (predicted_tool_pose(target, since_scan, clock_.now()).translation() - tip_).norm();
    if (residual <= config_.correction_tolerance) break;
  }

  check_interlocks();
  protocol::Mark mark;
  mark.defect_id = target.id;
  mark.outcome = MarkOutcome::kMarked;
  mark.reason = MarkReason::kNone;
  mark.time = clock_.now() + config_.epoch_offset;
  mark.tool_position = at.T_base_tool.translation();
  const auto est = motion_.latest();
  const double track_rms = est ? est->rms : 0.0;
  mark.estimated_error = std::sqrt(residual * residual + track_rms * track_rms);

  const double duration = config_.planner.spray_duration;
  events_->spraying(target.id);
  const std::uint16_t seq = robot_.spray(duration);
  // A robot that faults or drops off the link mid-spray closes the valve at once, not
  // at the pulse's end.
  const auto watch_robot = [this] {
    check_interlocks();
    check_robot(robot_.status());
  };
  if (!safety_.spray(duration, watch_robot)) {
    // The supervisor latched safe during the pulse: say why (the e-stop, mostly).
    if (safety_.estop_active()) throw JobAbort{MarkReason::kEmergencyStop, "e-stop during the spray"};
    throw JobAbort{MarkReason::kAborted, "sprayer valve refused: safety latched"};
  }
  wait_robot(seq, duration + config_.move_timeout_margin);
  const Transform retract = backed_off(at.T_base_tool, config_.retract_distance);
  if (limits.contains(retract.translation()))
    move_and_wait(retract, plan::move_time(config_.retract_distance, limits), Toward::kAway);
  return mark;
}

// The job's outcomes as they are decided: kept for the report, and passed on at once.
class JobRunner::Outcomes {
 public:
  Outcomes(std::uint64_t job_id, JobEvents& events, const clock::Clock& clock, double epoch_offset)
      : events_(events), clock_(clock), epoch_offset_(epoch_offset) {
    report.job_id = job_id;
  }
  void add(protocol::Mark m) {
    if (m.outcome != MarkOutcome::kMarked) m.time = clock_.now() + epoch_offset_;  // when given up
    report.marks.push_back(m);
    events_.reported(m);
  }
  // Every target left gets the same outcome.
  void give_up(std::vector<Target>& remaining, MarkOutcome outcome, MarkReason reason);
  protocol::MarkReport report;

 private:
  JobEvents& events_;
  const clock::Clock& clock_;
  double epoch_offset_;
};

void JobRunner::Outcomes::give_up(std::vector<Target>& remaining, MarkOutcome outcome, MarkReason reason) {
  for (const Target& t : remaining) add(unmarked(t.id, outcome, reason));
  remaining.clear();
}

std::vector<JobRunner::Target> JobRunner::targets_of(const protocol::DefectList& list,
                                                     Outcomes& outcomes) const {
  std::vector<Target> targets;
  for (const protocol::Defect& d : list.defects) {
    if (!markable(d.defect_class) || list.frame != "sls") {
      outcomes.add(unmarked(d.id, MarkOutcome::kSkipped, MarkReason::kNotMarkable));
      continue;
    }
    try {
      targets.push_back(Target{d.id, plan::defect_frame(d.position, d.normal)});
    } catch (const GeometryError&) {
      outcomes.add(unmarked(d.id, MarkOutcome::kSkipped, MarkReason::kNotMarkable));
    }
  }
  return targets;
}

bool JobRunner::wait_for_tracking(bool robot_live, double since) {
  const double deadline = clock_.now() + config_.tracking_timeout;
  const auto ready = [&] { return tracking_ok() && last_trusted_t_ >= since; };
  while (!ready() && clock_.now() < deadline && !cancelled_ && !motion_.failure()) {
    if (robot_live) {
      check_interlocks();
      robot_.heartbeat();
    }
    clock_.sleep_for(config_.poll_period);
  }
  return ready();
}

void JobRunner::start_robot() {
  robot_.connect();
  robot_.heartbeat();
  hal::RobotStatus s = robot_.status();
  if (s.state == robot_link::State::kStopped || s.state == robot_link::State::kFault) {
    // A stop the station itself caused (heartbeat pause between jobs, its own abort)
    // is cleared by starting a job, the operator's go-ahead, given only while the
    // e-stop is released. The robot's own faults (drive) need the robot's operator.
    if ((s.faults & ~robot_link::fault::kClearableByStation) != 0)
      throw JobAbort{MarkReason::kRobotFault, "robot " + std::string(robot_link::to_string(s.state)) + ": " +
                                                  robot_link::fault_names(s.faults) +
                                                  " (needs the robot's reset)"};
    check_interlocks();
    log::info("robot " + std::string(robot_link::to_string(s.state)) + " (" +
              robot_link::fault_names(s.faults) + "): resetting for the new job");
    s = robot_.wait_done(robot_.reset(), config_.robot_reset_timeout, config_.poll_period, clock_);
  }
  tip_ = s.T_base_tool.translation();
}

void JobRunner::mark_remaining(std::vector<Target>& remaining, const plan::MotionPredictor& since_scan,
                               Outcomes& outcomes) {
  while (!remaining.empty()) {
    check_interlocks();
    if (!tracking_ok() && !wait_for_tracking(true)) {
      outcomes.give_up(remaining, MarkOutcome::kSkipped, MarkReason::kTrackingLost);
      return;
    }
    // The planner orders what is left for the panel where it is now; the first goes next.
    std::vector<plan::DefectToMark> to_plan;
    for (const Target& t : remaining) to_plan.push_back({t.id, t.T_sls_v});
    const auto plan = plan::plan_marks(to_plan, tip_, clock_.now(), since_scan, config_.planner);
    if (plan.empty() || !plan.front().reachable) {
      outcomes.give_up(remaining, MarkOutcome::kSkipped, MarkReason::kOutOfReach);
      return;
    }
    const auto it = std::find_if(remaining.begin(), remaining.end(),
                                 [&](const Target& t) { return t.id == plan.front().id; });
    const Target target = *it;
    remaining.erase(it);
    try {
      outcomes.add(mark_one(target, since_scan));
    } catch (const SkipDefect& skip) {
      log::warn("defect " + std::to_string(target.id) + " skipped: " + skip.why);
      outcomes.add(unmarked(target.id, MarkOutcome::kSkipped, skip.reason));
    } catch (...) {
      remaining.insert(remaining.begin(), target);  // not decided: the job's abort reports it
      throw;
    }
  }
}

protocol::MarkReport JobRunner::run(const protocol::DefectList& list, double t_scan, JobEvents* events) {
  cancelled_ = false;
  last_trusted_t_ = -std::numeric_limits<double>::infinity();
  state_ = protocol::EdgeState::kJobReceived;
  JobEvents no_events;
  events_ = events ? events : &no_events;
  struct Detach {
    JobEvents*& e;
    ~Detach() { e = nullptr; }
  } detach{events_};
  Outcomes outcomes(list.job_id, *events_, clock_, config_.epoch_offset);
  std::vector<Target> remaining = targets_of(list, outcomes);
  // M since the scan: the motion source's M(t) composed with the inverse of M(t_scan).
  const plan::MotionPredictor since_scan = [this, t_scan](double t) {
    return motion_.predict(t) * motion_.predict(t_scan).inverse();
  };
  const std::string job = "job " + std::to_string(list.job_id);

  state_ = protocol::EdgeState::kTracking;
  // The first estimates are of the kept pairs since the scan, already old: the tool
  // sets off once the tracker has caught up to a pair taken after the job started, so
  // the first approach does not run out of estimate age while it catches up.
  if (!wait_for_tracking(false, clock_.now())) {
    log::warn(job + ": no tracking; nothing marked");
    outcomes.give_up(remaining, MarkOutcome::kSkipped, MarkReason::kTrackingLost);
    safety_.valve_off();
    state_ = protocol::EdgeState::kDone;
    return outcomes.report;
  }
  state_ = protocol::EdgeState::kMarking;
  if (!safety_.arm()) {
    log::error(job + ": e-stop pressed; nothing marked");
    outcomes.give_up(remaining, MarkOutcome::kFailed, MarkReason::kEmergencyStop);
    safety_.valve_off();
    state_ = protocol::EdgeState::kSafe;
    return outcomes.report;
  }
  // Any fault: the valve closes, the robot is aborted, the rest is reported with why.
  std::optional<MarkReason> fault;
  try {
    start_robot();
    mark_remaining(remaining, since_scan, outcomes);
  } catch (const JobAbort& a) {
    log::error(job + " stopped: " + a.why);
    fault = a.reason;
  } catch (const hal::RobotError& e) {
    log::error(job + " robot error: " + e.what());
    fault = e.kind() == hal::RobotError::Kind::kWaitTimeout ? MarkReason::kTimeout : MarkReason::kRobotFault;
  } catch (const std::exception& e) {
    log::error(job + " failed: " + e.what());
    fault = MarkReason::kAborted;
  }
  safety_.valve_off();
  if (fault) {
    outcomes.give_up(remaining, MarkOutcome::kFailed, *fault);
    try {
      robot_.abort();
    } catch (const std::exception& e) {
      log::error(std::string("robot abort failed (robot watchdog stops it): ") + e.what());
    }
  }
  state_ = fault ? protocol::EdgeState::kSafe : protocol::EdgeState::kDone;
  return outcomes.report;
}

}  // namespace dentmark::station
