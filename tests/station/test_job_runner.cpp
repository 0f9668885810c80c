// JobRunner against a mock robot (moves on the simulated clock, mirrors commands as
// state, records where it sprayed) and a motion source that knows the true motion.
#include <gtest/gtest.h>

#include <cmath>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/plan/marking_pose.h"
#include "dentmark/firmware/station/job_runner.h"

namespace dentmark::station {
namespace {

using protocol::MarkOutcome;
using protocol::MarkReason;

class MockRobot final : public hal::Robot {
 public:
  MockRobot(clock::Clock& clock, plan::RobotLimits limits) : clock_(clock), limits_(limits) {
    pose_.translation() = Eigen::Vector3d(0.3, 0.0, 0.4);
  }
  void connect() override { connected_ = true; }
  void disconnect() override { connected_ = false; }
  bool connected() const override { return connected_; }
  std::uint16_t move_to(const Transform& T, double) override {
    update();
    from_ = pose_;
    target_ = T;
    t_start_ = clock_.now();
    t_end_ = t_start_ + plan::move_time((T.translation() - pose_.translation()).norm(), limits_);
    state_ = robot_link::State::kMoving;
    return ++seq_;
  }
  std::uint16_t spray(double duration) override {
    update();
    sprays.push_back({clock_.now(), pose_});
    t_end_ = clock_.now() + duration;
    state_ = robot_link::State::kSpraying;
    return ++seq_;
  }
  std::uint16_t abort() override {
    ++aborts;
    state_ = robot_link::State::kStopped;
    return ++seq_;
  }
  std::uint16_t reset() override {
    state_ = robot_link::State::kIdle;
    return ++seq_;
  }
  void heartbeat() override {}
  hal::RobotStatus status() override {
    update();
    hal::RobotStatus s;
    s.sequence = seq_;
    s.state = state_;
    s.T_base_tool = pose_;
    return s;
  }
  struct Spray {
    double t;
    Transform pose;
  };
  std::vector<Spray> sprays;
  int aborts = 0;

 private:
  void update() {
    if (state_ == robot_link::State::kMoving) {
      const double now = clock_.now();
      const double f = t_end_ > t_start_ ? std::min(1.0, (now - t_start_) / (t_end_ - t_start_)) : 1.0;
      pose_ = target_;
      pose_.translation() = from_.translation() + f * (target_.translation() - from_.translation());
      if (f >= 1.0) state_ = robot_link::State::kIdle;
    } else if (state_ == robot_link::State::kSpraying && clock_.now() >= t_end_) {
      state_ = robot_link::State::kIdle;
    }
  }
  clock::Clock& clock_;
  plan::RobotLimits limits_;
  bool connected_ = false;
  Transform pose_ = Transform::Identity(), from_ = Transform::Identity(), target_ = Transform::Identity();
  double t_start_ = 0, t_end_ = 0;
  std::uint16_t seq_ = 0;
  robot_link::State state_ = robot_link::State::kIdle;
};

class MockSafety final : public SafetyIo {
 public:
  explicit MockSafety(clock::Clock& clock) : clock_(clock) {}
  bool estop_active() override { return estop_after >= 0 && clock_.now() >= estop_after; }
  bool spray(double duration) override {
    valve_open = true;
    pulses++;
    clock_.sleep_for(duration);
    valve_open = false;
    return true;
  }
  void valve_off() noexcept override {
    valve_open = false;
    offs++;
  }
  double estop_after = -1.0;
  bool valve_open = false;
  int pulses = 0, offs = 0;

 private:
  clock::Clock& clock_;
};

// The panel translates along camL x at the line speed; tracking can drop out.
class LineMotion final : public MotionSource {
 public:
  LineMotion(clock::Clock& clock, double speed) : clock_(clock), speed_(speed) {}
  std::optional<MotionEstimate> latest() override {
    MotionEstimate e;
    e.t = clock_.now();
    e.M_camL = predict(e.t);
    e.ok = !(lost_from >= 0 && e.t >= lost_from);
    e.quality = e.ok ? 1.0 : 0.0;
    e.features = 10;
    return e;
  }
  Transform predict(double t) override {
    Transform m = Transform::Identity();
    m.translation() = Eigen::Vector3d(speed_ * t, 0, 0);
    return m;
  }
  double lost_from = -1.0;

 private:
  clock::Clock& clock_;
  double speed_;
};

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
