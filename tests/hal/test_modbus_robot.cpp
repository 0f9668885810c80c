// The Linux Modbus client against the robot simulator over loopback TCP: motion with
// bounded speed and acceleration, sprays where the tip really is, workspace limits,
// the heartbeat watchdog, and injected faults (exception replies, late replies,
// dropped connections) leading to the behaviour docs/robot-modbus.md documents.
#include <gtest/gtest.h>

#include <cmath>
#include <numeric>

#include "robot_fixture.h"

namespace dentmark {
namespace {

namespace rl = robot_link;
using hal::ModbusRobot;
using hal::RobotError;
using test::pose;

class ModbusRobotTcp : public ::testing::Test {
 protected:
  void SetUp() override { start(test::sim_config()); }
  void start(const sim::robot::RobotSimConfig& cfg) {
    robot.reset();
    sim = sim::robot::RobotSimulator::serve_tcp(cfg, clock);
    ASSERT_GT(sim->port(), 0);
    robot = std::make_unique<ModbusRobot>(test::tcp_config(sim->port()), clock);
    robot->connect();
  }
  hal::RobotStatus wait(std::uint16_t seq, double timeout = 30.0) {
    return robot->wait_done(seq, timeout, 0.02, clock);
  }

  clock::SimClock clock{test::kRate};
  std::unique_ptr<sim::robot::RobotSimulator> sim;
  std::unique_ptr<ModbusRobot> robot;
};

TEST_F(ModbusRobotTcp, MoveReachesTargetWithinSpeedAndAccelerationLimits) {
  const auto start_pose = sim->nominal_pose();
  const auto target = pose(0.4, 0.3, 0.5);  // 0.3 m along y from home, same orientation
  const auto seq = robot->move_to(target, 0.2);
  const auto s = wait(seq);
  EXPECT_EQ(s.sequence, seq);
  EXPECT_EQ(s.faults, 0);
  EXPECT_LT((s.T_base_tool.translation() - target.translation()).norm(), 1e-4);  // 0.1 mm register units
  EXPECT_LT(rotation_angle_between(s.T_base_tool, target), 2e-3);
  EXPECT_NEAR(s.tool_speed, 0.0, 1e-9);

  // Closed form for 0.3 m at v 0.2 m/s, a 1 m/s²: 0.2 s ramps, 0.26 m cruise -> 1.7 s.
  const auto traj = sim->trajectory();
  ASSERT_GE(traj.size(), 20u);
  double t_start = -1, t_end = -1, v_max = 0;
  for (const auto& p : traj) {
    v_max = std::max(v_max, p.speed);
    if (t_start < 0 && (p.T_base_tool.translation() - start_pose.translation()).norm() > 0) t_start = p.time;
  }
  t_end = traj.back().time;
  EXPECT_LE(v_max, 0.2 + 1e-7);  // the speed register is float32: 0.2f = 0.2000000030
  EXPECT_GT(v_max, 0.2 * 0.99);  // reaches the cruise speed
  // The first moving sample is at most one poll step (<= 10 ms real) after the start.
  EXPECT_NEAR(t_end - t_start, 1.7, 0.1);
  // Accelerations between successive samples stay within 1 m/s² (plus sampling slack).
  for (std::size_t i = 1; i < traj.size(); ++i) {
    const double dt = traj[i].time - traj[i - 1].time;
    if (dt > 0.005) {
      EXPECT_LE(std::abs(traj[i].speed - traj[i - 1].speed) / dt, 1.0 + 1e-6);
    }
  }
  // Straight line: every sample lies on the segment from start to target.
  const Eigen::Vector3d a = start_pose.translation(), b = target.translation();
  for (const auto& p : traj) {
    const Eigen::Vector3d q = p.T_base_tool.translation();
    EXPECT_LT(((q - a).cross(b - a)).norm() / (b - a).norm(), 1e-9);
  }
}

TEST_F(ModbusRobotTcp, SprayIsRecordedWhereTheTipReallyIs) {
  auto cfg = test::sim_config();
  cfg.accuracy_error =
      make_transform_rotvec(Eigen::Vector3d(0, 0, 0.002), Eigen::Vector3d(0.0012, -0.0007, 0.0003));
  start(cfg);
  const auto target = pose(0.35, -0.1, 0.45);
  wait(robot->move_to(target, 0.0));
  const auto seq = robot->spray(0.05);
  const auto s = wait(seq);
  EXPECT_EQ(s.spray_count, 1u);
  const auto sprays = sim->sprays();
  ASSERT_EQ(sprays.size(), 1u);
  EXPECT_EQ(sprays[0].sequence, seq);
  EXPECT_DOUBLE_EQ(sprays[0].duration, 0.05);
  // The robot believes it is at the (quantised) target; the tip is off by the accuracy error.
  EXPECT_LT((sprays[0].T_base_tool.translation() - target.translation()).norm(), 1e-4);
  const Transform expected_tip = cfg.accuracy_error * sprays[0].T_base_tool;
  EXPECT_LT((sprays[0].T_base_tip.translation() - expected_tip.translation()).norm(), 1e-12);
  EXPECT_GT((sprays[0].T_base_tip.translation() - sprays[0].T_base_tool.translation()).norm(), 1e-3);
}

TEST_F(ModbusRobotTcp, RepeatabilityNoiseHasTheConfiguredSpread) {
  auto cfg = test::sim_config();
  cfg.repeatability = 0.0002;  // 0.2 mm
  start(cfg);
  const auto a = pose(0.40, 0.00, 0.50), b = pose(0.40, 0.01, 0.50);
  std::vector<double> dev;
  for (int i = 0; i < 30; ++i) {
    wait(robot->move_to(i % 2 ? a : b, 0.0));
    const auto tip = sim->true_pose();
    const auto nominal = sim->nominal_pose();
    for (int k = 0; k < 3; ++k) dev.push_back(tip.translation()(k) - nominal.translation()(k));
  }
  const double mean = std::accumulate(dev.begin(), dev.end(), 0.0) / dev.size();
  double var = 0;
  for (double d : dev) var += (d - mean) * (d - mean);
  const double sigma = std::sqrt(var / (dev.size() - 1));
  // 90 samples: the estimate of σ is within ~±25 % at 3 standard errors.
  EXPECT_NEAR(sigma, 0.0002, 0.00005);
}

TEST_F(ModbusRobotTcp, TargetOutsideWorkspaceIsRejectedAndResetClearsIt) {
  const auto home = sim->nominal_pose();
  const auto seq = robot->move_to(pose(0.4, 0.0, 2.0), 0.1);  // z above the 1.2 m limit
  try {
    wait(seq);
    FAIL() << "expected a rejection";
  } catch (const RobotError& e) {
    EXPECT_EQ(e.kind(), RobotError::Kind::kRejected);
    EXPECT_NE(std::string(e.what()).find("workspace"), std::string::npos) << e.what();
  }
  auto s = robot->status();
  EXPECT_EQ(s.state, rl::State::kFault);
  EXPECT_EQ(s.faults, rl::fault::kWorkspace);
  EXPECT_LT((sim->nominal_pose().translation() - home.translation()).norm(), 1e-12);  // did not move
  s = wait(robot->reset());
  EXPECT_EQ(s.state, rl::State::kIdle);
  EXPECT_EQ(s.faults, 0);
}

TEST_F(ModbusRobotTcp, RobotStopsWhenHeartbeatsStop) {
  const auto target = pose(0.4, 0.6, 0.5);
  robot->move_to(target, 0.05);  // 0.6 m at 0.05 m/s: 12 s
  // Keep the heartbeat going for 1 s, then go silent (a stalled edge).
  double last_beat = clock.now();
  for (int i = 0; i < 10; ++i) {
    clock.sleep_for(0.1);
    robot->heartbeat();
    last_beat = clock.now();
  }
  EXPECT_EQ(robot->status().state, rl::State::kMoving);
  clock.sleep_for(1.5);  // > heartbeat_timeout of 1 s
  const auto s = robot->status();
  EXPECT_EQ(s.state, rl::State::kStopped);
  EXPECT_EQ(s.faults, rl::fault::kHeartbeatLost);
  EXPECT_NEAR(s.tool_speed, 0.0, 1e-9);
  EXPECT_GT((s.T_base_tool.translation() - target.translation()).norm(), 0.4);  // stopped short
  // It stopped within the timeout (plus a poll step) of the last heartbeat.
  const auto traj = sim->trajectory();
  EXPECT_NEAR(traj.back().time - last_beat, 1.0, 0.1);
  // A stopped robot stays still.
  const auto still = sim->nominal_pose();
  clock.sleep_for(0.5);
  EXPECT_LT((sim->nominal_pose().translation() - still.translation()).norm(), 1e-12);
  // Heartbeats back plus a reset make it usable again.
  wait(robot->reset());
  EXPECT_EQ(wait(robot->move_to(pose(0.4, 0.0, 0.5), 0.0)).state, rl::State::kIdle);
}

TEST_F(ModbusRobotTcp, AbortStopsTheMove) {
  const auto seq = robot->move_to(pose(0.4, 0.5, 0.5), 0.05);
  clock.sleep_for(0.5);
  robot->heartbeat();  // within the 1 s heartbeat timeout: it is the abort that stops it
  clock.sleep_for(0.5);
  robot->abort();
  const auto s = robot->status();
  EXPECT_EQ(s.state, rl::State::kStopped);
  EXPECT_EQ(s.faults, rl::fault::kAborted);
  EXPECT_NE(s.sequence, seq);
  EXPECT_LT(s.T_base_tool.translation().y(), 0.1);
  clock.sleep_for(0.5);
  // It braked within the acceleration limit (0.05 m/s to 0 at 1 m/s²: 0.05 s, 1.25 mm) and stays put.
  const auto traj = sim->trajectory();
  for (std::size_t i = 1; i < traj.size(); ++i) {
    const double dt = traj[i].time - traj[i - 1].time;
    if (dt > 0.005) {
      EXPECT_LE(std::abs(traj[i].speed - traj[i - 1].speed) / dt, 1.0 + 1e-6)
          << "at " << traj[i].time << " prev " << traj[i - 1].time << " " << traj[i - 1].speed << " now "
          << traj[i].speed;
    }
  }
  EXPECT_EQ(traj.back().speed, 0.0);
  const auto braked = robot->status();
  EXPECT_EQ(braked.tool_speed, 0.0f);
  EXPECT_LT((braked.T_base_tool.translation() - s.T_base_tool.translation()).norm(), 0.0013 + 1e-4);
}

TEST_F(ModbusRobotTcp, ExceptionReplyIsReportedWithoutDroppingTheLink) {
  sim->inject_exception(4, 1);  // 4: server device failure
  try {
    robot->status();
    FAIL() << "expected an exception reply";
  } catch (const RobotError& e) {
    EXPECT_EQ(e.kind(), RobotError::Kind::kException);
    EXPECT_NE(std::string(e.what()).find("exception reply"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(robot->connected());
  EXPECT_EQ(robot->counters().exceptions, 1);
  EXPECT_EQ(robot->status().state, rl::State::kIdle);
  EXPECT_EQ(robot->counters().reconnects, 1);
}

TEST_F(ModbusRobotTcp, LateReplyTimesOutThenReconnectAndRetrySucceed) {
  sim->inject_delay(0.8, 1);  // > 0.5 s request timeout, < twice it
  const auto s = robot->status();
  EXPECT_EQ(s.state, rl::State::kIdle);
  EXPECT_EQ(robot->counters().timeouts, 1);
  EXPECT_EQ(robot->counters().reconnects, 2);
}

TEST_F(ModbusRobotTcp, RetriedCommandRunsOnce) {
  wait(robot->move_to(pose(0.4, 0.0, 0.5), 0.0));
  sim->inject_delay(0.8, 1);  // the robot takes the spray, its reply comes too late
  const auto seq = robot->spray(0.02);
  EXPECT_EQ(robot->counters().timeouts, 1);
  wait(seq);
  EXPECT_EQ(sim->sprays().size(), 1u);  // the retry carried the same sequence number
  EXPECT_EQ(robot->status().spray_count, 1u);
}

TEST_F(ModbusRobotTcp, PersistentTimeoutThrowsTimeout) {
  sim->inject_delay(0.8, 2);
  try {
    robot->status();
    FAIL() << "expected a timeout";
  } catch (const RobotError& e) {
    EXPECT_EQ(e.kind(), RobotError::Kind::kTimeout) << e.what();
    EXPECT_NE(std::string(e.what()).find("127.0.0.1:" + std::to_string(sim->port())), std::string::npos);
  }
  EXPECT_FALSE(robot->connected());
  EXPECT_EQ(robot->counters().timeouts, 2);
  clock.sleep_for(1.0);                                // the simulator finishes its late replies
  EXPECT_EQ(robot->status().state, rl::State::kIdle);  // reconnects
}

TEST_F(ModbusRobotTcp, DroppedConnectionIsReconnected) {
  sim->inject_drop(1);
  EXPECT_EQ(robot->status().state, rl::State::kIdle);
  EXPECT_EQ(robot->counters().reconnects, 2);
  EXPECT_EQ(sim->connections(), 2);
}

TEST_F(ModbusRobotTcp, RobotGoneGivesDisconnectedAndBackoff) {
  const int port = sim->port();
  sim.reset();  // robot controller powered off
  EXPECT_THROW(robot->status(), RobotError);
  ModbusRobot late(test::tcp_config(port), clock, 1000.0);
  try {
    late.connect();
    FAIL();
  } catch (const RobotError& e) {
    EXPECT_EQ(e.kind(), RobotError::Kind::kDisconnected);
    EXPECT_NE(std::string(e.what()).find("127.0.0.1:" + std::to_string(port)), std::string::npos) << e.what();
  }
  try {
    late.status();  // within the backoff: no new attempt
    FAIL();
  } catch (const RobotError& e) {
    EXPECT_EQ(e.kind(), RobotError::Kind::kDisconnected);
    EXPECT_NE(std::string(e.what()).find("reconnect pending"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace dentmark
