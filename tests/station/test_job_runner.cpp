// JobRunner against a mock robot (moves on the simulated clock, mirrors commands as
// state, records where it sprayed) and a motion source that knows the true motion.
#include <gtest/gtest.h>

#include <cmath>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/plan/marking_pose.h"
#include "dentmark/firmware/station/job_runner.h"
#include "station_fakes.h"

namespace dentmark::station {
namespace {

using protocol::MarkOutcome;
using protocol::MarkReason;
using testing::LineMotion;
using testing::MockRobot;
using testing::MockSafety;

JobConfig config() {
  JobConfig c;
  c.planner.limits.workspace_min = Eigen::Vector3d(-1, -1, -0.2);
  c.planner.limits.workspace_max = Eigen::Vector3d(1.5, 1, 1);
  c.planner.chain.standoff = 0.03;
  c.poll_period = 0.005;
  return c;
}

protocol::DefectList list_of(std::initializer_list<std::pair<double, double>> xy) {
  protocol::DefectList list;
  list.job_id = 42;
  std::uint32_t id = 1;
  for (auto [x, y] : xy) {
    protocol::Defect d;
    d.id = id++;
    d.defect_class = protocol::DefectClass::kDent;
    d.position = Eigen::Vector3d(x, y, 0.0);
    d.normal = Eigen::Vector3d::UnitZ();
    list.defects.push_back(d);
  }
  return list;
}

TEST(JobRunner, MarksEveryDefectWhereItIsWhenTheSprayerFires) {
  clock::SimClock clock;  // manual: sleeps jump time, so the test runs instantly
  const JobConfig cfg = config();
  MockRobot robot(clock, cfg.planner.limits);
  MockSafety safety(clock);
  const double speed = 0.014;
  LineMotion motion(clock, speed);
  JobRunner runner(robot, safety, motion, clock, cfg);
  auto list = list_of({{0.1, 0.0}, {0.4, 0.1}, {-0.2, -0.1}});
  list.defects.push_back(list.defects[0]);
  list.defects.back().id = 9;
  list.defects.back().defect_class = protocol::DefectClass::kDesignFeature;

  const auto report = runner.run(list, 0.0);
  EXPECT_EQ(runner.state(), protocol::EdgeState::kDone);
  ASSERT_EQ(report.marks.size(), 4u);
  ASSERT_EQ(robot.sprays.size(), 3u);
  EXPECT_EQ(safety.pulses, 3);
  EXPECT_FALSE(safety.valve_open);
  int marked = 0;
  for (std::size_t i = 0; i < report.marks.size(); ++i) {
    const auto& m = report.marks[i];
    if (m.defect_id == 9) {
      EXPECT_EQ(m.outcome, MarkOutcome::kSkipped);
      EXPECT_EQ(m.reason, MarkReason::kNotMarkable);
      continue;
    }
    ASSERT_EQ(m.outcome, MarkOutcome::kMarked);
    const auto& spray = robot.sprays[marked++];
    const auto& d = list.defects[m.defect_id - 1];
    // Truth: the defect at spray time, plus standoff along the normal.
    const Eigen::Vector3d expected = d.position + Eigen::Vector3d(speed * spray.t, 0, 0) + 0.03 * d.normal;
    EXPECT_LT((spray.pose.translation() - expected).norm(), 0.5e-3) << "defect " << m.defect_id;
    EXPECT_NEAR(spray.pose.linear().col(2).dot(-d.normal), 1.0, 1e-9);  // tool points into the surface
    EXPECT_NEAR(m.time, spray.t, 1e-9);
  }
}

TEST(JobRunner, EstopDuringJobFailsTheRestAndGoesSafe) {
  clock::SimClock clock;
  const JobConfig cfg = config();
  MockRobot robot(clock, cfg.planner.limits);
  MockSafety safety(clock);
  LineMotion motion(clock, 0.014);
  safety.estop_after = 2.5;  // during the second defect
  JobRunner runner(robot, safety, motion, clock, cfg);
  const auto report = runner.run(list_of({{0.1, 0.0}, {0.6, 0.0}, {-0.4, 0.0}}), 0.0);
  EXPECT_EQ(runner.state(), protocol::EdgeState::kSafe);
  EXPECT_GE(robot.aborts, 1);
  EXPECT_FALSE(safety.valve_open);
  EXPECT_GE(safety.offs, 1);
  int estopped = 0;
  for (const auto& m : report.marks)
    if (m.outcome == MarkOutcome::kFailed && m.reason == MarkReason::kEmergencyStop) ++estopped;
  EXPECT_GE(estopped, 1);
  EXPECT_EQ(report.marks.size(), 3u);
  // Nothing sprayed after the e-stop.
  for (const auto& s : robot.sprays) EXPECT_LT(s.t, 2.5);
}

TEST(JobRunner, LostTrackingSkipsInsteadOfGuessing) {
  clock::SimClock clock;
  JobConfig cfg = config();
  cfg.tracking_timeout = 1.0;
  MockRobot robot(clock, cfg.planner.limits);
  MockSafety safety(clock);
  LineMotion motion(clock, 0.014);
  motion.lost_from = 0.0;
  JobRunner runner(robot, safety, motion, clock, cfg);
  const auto report = runner.run(list_of({{0.1, 0.0}, {0.2, 0.0}}), 0.0);
  ASSERT_EQ(report.marks.size(), 2u);
  for (const auto& m : report.marks) {
    EXPECT_EQ(m.outcome, MarkOutcome::kSkipped);
    EXPECT_EQ(m.reason, MarkReason::kTrackingLost);
  }
  EXPECT_TRUE(robot.sprays.empty());
}

TEST(JobRunner, LostTrackingDuringTheApproachStopsTheToolThere) {
  // The tool is on its way to a defect where the tracker predicted it when the tracker
  // loses the panel: the tool is stopped at the next poll, not sent on along a stale
  // prediction, and the job ends with the rest failed / tracking_lost.
  clock::SimClock clock;
  JobConfig cfg = config();
  MockRobot robot(clock, cfg.planner.limits);
  MockSafety safety(clock);
  LineMotion motion(clock, 0.014);
  motion.lost_from = 0.2;  // the first approach takes longer than that
  JobRunner runner(robot, safety, motion, clock, cfg);
  const auto report = runner.run(list_of({{0.1, 0.0}, {0.2, 0.0}}), 0.0);
  EXPECT_EQ(runner.state(), protocol::EdgeState::kSafe);
  ASSERT_EQ(report.marks.size(), 2u);
  for (const auto& m : report.marks) {
    EXPECT_EQ(m.outcome, MarkOutcome::kFailed);
    EXPECT_EQ(m.reason, MarkReason::kTrackingLost);
  }
  EXPECT_TRUE(robot.sprays.empty());
  EXPECT_EQ(robot.aborts, 1);
  EXPECT_GE(robot.aborted_at, 0.2);
  EXPECT_LE(robot.aborted_at, 0.2 + 2 * cfg.poll_period);
  EXPECT_FALSE(safety.valve_open);
}

TEST(JobRunner, TheToolSetsOffOnceTheTrackerHasCaughtUp) {
  // The job starts while the tracker still works through the pairs kept since the scan:
  // its newest estimate is of a pair 0.3 s old, within max_estimate_age (0.5 s), but
  // it stays that until the tracker catches up at 0.25 s. Setting off at once, the
  // first approach would run out of estimate age at 0.2 s; the tool waits instead.
  const JobConfig cfg = config();
  clock::SimClock clock;
  MockRobot robot(clock, cfg.planner.limits);
  MockSafety safety(clock);
  LineMotion motion(clock, 0.014);
  motion.behind_at = -0.3;
  motion.caught_up_at = 0.25;
  JobRunner runner(robot, safety, motion, clock, cfg);
  const auto report = runner.run(list_of({{0.1, 0.0}, {0.2, 0.0}}), -0.4);
  EXPECT_EQ(runner.state(), protocol::EdgeState::kDone);
  ASSERT_EQ(report.marks.size(), 2u);
  for (const auto& m : report.marks) EXPECT_EQ(m.outcome, MarkOutcome::kMarked);
  EXPECT_GE(robot.first_move_at, motion.caught_up_at);
  EXPECT_LE(robot.first_move_at, motion.caught_up_at + 2 * cfg.poll_period);
}

TEST(JobRunner, ABriefSpellOfPoorEstimatesIsCoastedThrough) {
  // One bad stereo pair, or the arm across the cameras for a moment: estimates of poor
  // quality for less than max_estimate_age during the first approach. They are no
  // information; the job steers on by the trusted ones and marks every defect where it
  // is. Longer than max_estimate_age, and the job ends tracking_lost as above.
  const JobConfig cfg = config();
  const auto list = list_of({{0.1, 0.0}, {0.2, 0.0}});
  for (const double spell : {0.6 * cfg.max_estimate_age, 1.6 * cfg.max_estimate_age}) {
    clock::SimClock clock;
    MockRobot robot(clock, cfg.planner.limits);
    MockSafety safety(clock);
    LineMotion motion(clock, 0.014);
    motion.poor_from = 0.2;  // the first approach takes longer than that
    motion.poor_until = 0.2 + spell;
    JobRunner runner(robot, safety, motion, clock, cfg);
    const auto report = runner.run(list, 0.0);
    ASSERT_EQ(report.marks.size(), 2u);
    if (spell < cfg.max_estimate_age) {
      EXPECT_EQ(runner.state(), protocol::EdgeState::kDone) << "spell " << spell << " s";
      for (const auto& m : report.marks)
        EXPECT_EQ(m.outcome, MarkOutcome::kMarked) << "spell " << spell << " s";
      ASSERT_EQ(robot.sprays.size(), 2u);
      for (const auto& spray : robot.sprays) {  // each on a defect where it is then
        double nearest = 1.0;
        for (const auto& d : list.defects)
          nearest =
              std::min(nearest, (spray.pose.translation() -
                                 (d.position + Eigen::Vector3d(0.014 * spray.t, 0, 0) + 0.03 * d.normal))
                                    .norm());
        EXPECT_LT(nearest, 0.5e-3);
      }
      EXPECT_EQ(robot.aborts, 0);
    } else {
      EXPECT_EQ(runner.state(), protocol::EdgeState::kSafe) << "spell " << spell << " s";
      for (const auto& m : report.marks) EXPECT_EQ(m.reason, MarkReason::kTrackingLost);
      EXPECT_GE(robot.aborted_at, 0.2 + cfg.max_estimate_age - cfg.poll_period);
      EXPECT_LE(robot.aborted_at, 0.2 + cfg.max_estimate_age + 2 * cfg.poll_period);
    }
  }
}

TEST(JobRunner, DeadCamerasEndTheJobAtTheNextCheckEvenMidSpray) {
  // The first spray's time from the same job with working cameras; then the cameras die
  // 50 ms into that pulse: the valve closes at the next check (10 ms), the robot is
  // stopped, and both defects are reported failed / tracking_lost (the first may carry
  // paint and is never sprayed again).
  const JobConfig cfg = config();
  const auto list = list_of({{0.1, 0.0}, {0.6, 0.0}});
  double t_spray = 0.0;
  {
    clock::SimClock clock;
    MockRobot robot(clock, cfg.planner.limits);
    MockSafety safety(clock);
    LineMotion motion(clock, 0.014);
    JobRunner runner(robot, safety, motion, clock, cfg);
    ASSERT_EQ(runner.run(list, 0.0).marks.size(), 2u);
    ASSERT_EQ(robot.sprays.size(), 2u);
    t_spray = robot.sprays[0].t;
  }
  clock::SimClock clock;
  MockRobot robot(clock, cfg.planner.limits);
  MockSafety safety(clock);
  LineMotion motion(clock, 0.014);
  motion.failed_from = t_spray + 0.05;
  JobRunner runner(robot, safety, motion, clock, cfg);
  const auto report = runner.run(list, 0.0);
  EXPECT_EQ(runner.state(), protocol::EdgeState::kSafe);
  ASSERT_EQ(report.marks.size(), 2u);
  for (const auto& m : report.marks) {
    EXPECT_EQ(m.outcome, MarkOutcome::kFailed);
    EXPECT_EQ(m.reason, MarkReason::kTrackingLost);
    EXPECT_LE(m.time, motion.failed_from + 0.011);
  }
  EXPECT_EQ(safety.pulses, 1);
  EXPECT_GE(safety.cut_at, motion.failed_from);
  EXPECT_LE(safety.cut_at, motion.failed_from + 0.011);
  EXPECT_FALSE(safety.valve_open);
  EXPECT_GE(robot.aborts, 1);
  EXPECT_LE(robot.aborted_at, motion.failed_from + 0.011);
}

TEST(JobRunner, RefusesToMarkWhenTheTrackerIsUnsure) {
  clock::SimClock clock;
  JobConfig cfg = config();
  cfg.tracking_timeout = 1.0;
  MockRobot robot(clock, cfg.planner.limits);
  MockSafety safety(clock);
  LineMotion motion(clock, 0.014);
  motion.expected_error = 1.5 * cfg.trust.max_expected_error;  // ok and quality 1, but unsure
  JobRunner runner(robot, safety, motion, clock, cfg);
  const auto report = runner.run(list_of({{0.1, 0.0}}), 0.0);
  ASSERT_EQ(report.marks.size(), 1u);
  EXPECT_EQ(report.marks[0].outcome, MarkOutcome::kSkipped);
  EXPECT_EQ(report.marks[0].reason, MarkReason::kTrackingLost);
  EXPECT_TRUE(robot.sprays.empty());
}

TEST(JobRunner, OutOfReachDefectsAreSkippedWithReason) {
  clock::SimClock clock;
  JobConfig cfg = config();
  cfg.planner.horizon = 5.0;
  MockRobot robot(clock, cfg.planner.limits);
  MockSafety safety(clock);
  LineMotion motion(clock, 0.014);
  JobRunner runner(robot, safety, motion, clock, cfg);
  const auto report = runner.run(list_of({{0.2, 0.0}, {-5.0, 0.0}}), 0.0);
  ASSERT_EQ(report.marks.size(), 2u);
  EXPECT_EQ(report.marks[0].outcome, MarkOutcome::kMarked);
  EXPECT_EQ(report.marks[1].outcome, MarkOutcome::kSkipped);
  EXPECT_EQ(report.marks[1].reason, MarkReason::kOutOfReach);
  EXPECT_EQ(runner.state(), protocol::EdgeState::kDone);
}

}  // namespace
}  // namespace dentmark::station
