// The Modbus client against the simulator over RTU, through a pty pair made by socat
// (the two ends stand for the edge's and the robot's serial ports).
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cstdlib>
#include <filesystem>

#include "robot_fixture.h"
#include "subprocess.h"

namespace dentmark {
namespace {

namespace rl = robot_link;
using hal::ModbusRobot;
using hal::RobotError;
using test::pose;

class ModbusRobotRtu : public ::testing::Test {
 protected:
  void SetUp() override {
    char tmpl[] = "/tmp/dentmark-rtu-XXXXXX";
    ASSERT_NE(::mkdtemp(tmpl), nullptr);
    dir_ = tmpl;
    const std::string robot_end = dir_ + "/robot", edge_end = dir_ + "/edge";
    // socat is required (scripts/setup-deps installs it): a missing tool fails, never skips.
    socat_ = test::spawn({"socat", "pty,raw,echo=0,link=" + robot_end, "pty,raw,echo=0,link=" + edge_end});
    for (int i = 0; i < 500 && !(std::filesystem::exists(robot_end) && std::filesystem::exists(edge_end));
         ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    ASSERT_TRUE(std::filesystem::exists(edge_end)) << "socat made no pty pair in 5 s";
    sim::robot::RtuEndpoint ep;
    ep.device = robot_end;
    ep.baud = 115200;
    sim_ = sim::robot::RobotSimulator::serve_rtu(test::sim_config(), clock_, ep);
    board::ModbusConfig m;
    m.transport = board::ModbusTransport::kRtu;
    m.device = edge_end;
    m.baud = 115200;
    m.unit_id = 1;
    m.timeout = 0.5;
    robot_ = std::make_unique<ModbusRobot>(m, clock_);
    robot_->connect();
  }
  void TearDown() override {
    robot_.reset();
    sim_.reset();
    if (socat_ > 0) {
      ::kill(socat_, SIGTERM);
      test::wait_exit(socat_, 5.0);
    }
    std::filesystem::remove_all(dir_);
  }
  hal::RobotStatus wait(std::uint16_t seq) { return robot_->wait_done(seq, 30.0, 0.02, clock_); }

  clock::SimClock clock_{test::kRate};
  std::string dir_;
  pid_t socat_ = -1;
  std::unique_ptr<sim::robot::RobotSimulator> sim_;
  std::unique_ptr<ModbusRobot> robot_;
};

TEST_F(ModbusRobotRtu, MoveAndSpray) {
  const auto target = pose(0.45, -0.05, 0.55);
  auto s = wait(robot_->move_to(target, 0.0));
  EXPECT_LT((s.T_base_tool.translation() - target.translation()).norm(), 1e-4);
  s = wait(robot_->spray(0.03));
  EXPECT_EQ(s.spray_count, 1u);
  ASSERT_EQ(sim_->sprays().size(), 1u);
  EXPECT_LT((sim_->sprays()[0].T_base_tip.translation() - target.translation()).norm(), 1e-4);
}

TEST_F(ModbusRobotRtu, ExceptionReply) {
  sim_->inject_exception(2, 1);  // illegal data address
  try {
    robot_->status();
    FAIL();
  } catch (const RobotError& e) {
    EXPECT_EQ(e.kind(), RobotError::Kind::kException);
    EXPECT_NE(std::string(e.what()).find("modbus rtu " + dir_ + "/edge"), std::string::npos) << e.what();
  }
  EXPECT_EQ(robot_->status().state, rl::State::kIdle);
}

TEST_F(ModbusRobotRtu, LateReplyIsFlushedAndTheRetrySucceeds) {
  sim_->inject_delay(0.8, 1);
  EXPECT_EQ(robot_->status().state, rl::State::kIdle);
  EXPECT_EQ(robot_->counters().timeouts, 1);
  EXPECT_EQ(robot_->counters().reconnects, 1);  // the serial port stayed open
  // The stale reply is gone: later requests pair with their own replies.
  const auto s = wait(robot_->move_to(pose(0.4, 0.05, 0.5), 0.0));
  EXPECT_NEAR(s.T_base_tool.translation().y(), 0.05, 1e-4);
}

TEST_F(ModbusRobotRtu, OtherUnitIdGetsNoAnswer) {
  board::ModbusConfig m;
  m.transport = board::ModbusTransport::kRtu;
  m.device = dir_ + "/edge";
  m.unit_id = 7;
  m.timeout = 0.1;
  robot_.reset();  // one master on the line
  ModbusRobot other(m, clock_);
  try {
    other.connect();
    FAIL();
  } catch (const RobotError& e) {
    EXPECT_EQ(e.kind(), RobotError::Kind::kTimeout) << e.what();
  }
}

}  // namespace
}  // namespace dentmark
