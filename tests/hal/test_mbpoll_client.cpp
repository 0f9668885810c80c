// An independent Modbus client (Debian's mbpoll, built on its own copy of the
// protocol handling) drives the robot simulator: proves the simulator speaks the
// documented map, addresses and word order, not just whatever our client expects.
#include <gtest/gtest.h>

#include <map>
#include <regex>

#include "robot_fixture.h"
#include "subprocess.h"

namespace dentmark {
namespace {

namespace rl = robot_link;

// Parses mbpoll's "[addr]: value" lines.
std::map<int, std::string> parse_mbpoll(const std::string& out) {
  std::map<int, std::string> values;
  const std::regex line(R"(\[(\d+)\]:\s*(\S+))");
  for (auto it = std::sregex_iterator(out.begin(), out.end(), line); it != std::sregex_iterator(); ++it)
    values[std::stoi((*it)[1])] = (*it)[2];
  return values;
}

class MbpollClient : public ::testing::Test {
 protected:
  void SetUp() override {
    auto cfg = test::sim_config();
    cfg.heartbeat_timeout = 20.0;  // one mbpoll run per request: slow heartbeats
    sim_ = sim::robot::RobotSimulator::serve_tcp(cfg, clock_);
  }
  test::Completed mbpoll(std::vector<std::string> args) {
    std::vector<std::string> cmd{"mbpoll", "-m", "tcp", "-p", std::to_string(sim_->port()), "-a", "1",
                                 "-0",     "-1", "-o",  "2"};
    cmd.insert(cmd.end(), args.begin(), args.end());
    auto done = test::run(cmd, 20.0);
    EXPECT_EQ(done.exit_code, 0) << done.output;
    return done;
  }
  std::map<int, std::string> status() {
    return parse_mbpoll(mbpoll({"-t", "3", "-r", "0", "-c", "16", "127.0.0.1"}).output);
  }

  clock::SimClock clock_{10.0};
  std::unique_ptr<sim::robot::RobotSimulator> sim_;
};

TEST_F(MbpollClient, DrivesTheSimulatorThroughTheDocumentedMap) {
  // Speed limit as float32, high word first (mbpoll -B), written on its own: no new
  // sequence, so no command yet.
  mbpoll({"-B", "-t", "4:float", "-r", std::to_string(rl::cmd::kSpeed), "127.0.0.1", "0.125"});
  EXPECT_EQ(sim_->state(), rl::State::kIdle);
  // Move: command 1, sequence 1, heartbeat 1, spray 0, x 0.42 m, y -0.1 m, z 0.5 m, rx 3.0 rad.
  // mbpoll takes 16-bit registers unsigned: -1000 is written as its two's complement 64536.
  mbpoll({"-t", "4", "-r", "0", "127.0.0.1", "1", "1", "1", "0", "4200", "64536", "5000", "3000", "0", "0"});
  std::map<int, std::string> s;
  for (int i = 0; i < 100; ++i) {
    s = status();
    if (s[rl::status::kSequence] == "1" && s[rl::status::kState] == "0") break;
    clock_.sleep_for(0.2);
  }
  ASSERT_EQ(s.size(), 16u);
  EXPECT_EQ(s[rl::status::kSequence], "1");
  EXPECT_EQ(s[rl::status::kState], "0");
  EXPECT_EQ(s[rl::status::kFaults], "0");
  EXPECT_EQ(s[rl::status::kHeartbeat], "1");
  EXPECT_EQ(s[rl::status::kToolPose + 0], "4200");
  EXPECT_EQ(s[rl::status::kToolPose + 1], "64536");
  EXPECT_EQ(s[rl::status::kToolPose + 2], "5000");
  EXPECT_EQ(s[rl::status::kToolPose + 3], "3000");
  const Transform nominal = sim_->nominal_pose();
  EXPECT_NEAR(nominal.translation().x(), 0.42, 1e-12);
  EXPECT_NEAR(nominal.translation().y(), -0.10, 1e-12);
  // The float speed limit mbpoll wrote was honoured: the tool never exceeded 0.125 m/s and reached it.
  double v_max = 0;
  for (const auto& p : sim_->trajectory()) v_max = std::max(v_max, p.speed);
  EXPECT_NEAR(v_max, 0.125, 1e-6);

  // Spray 40 ms, sequence 2; then read the 32-bit spray counter as mbpoll -B int.
  mbpoll({"-t", "4", "-r", "0", "127.0.0.1", "2", "2", "2", "40"});
  // The simulator replies to the write before it acts on the command block (as a
  // controller does: the reply only confirms the registers): wait for the spray.
  for (int i = 0; i < 200 && sim_->sprays().empty(); ++i) clock_.sleep_for(0.01);
  ASSERT_EQ(sim_->sprays().size(), 1u);
  EXPECT_EQ(sim_->sprays()[0].sequence, 2);
  EXPECT_DOUBLE_EQ(sim_->sprays()[0].duration, 0.04);
  const auto count = parse_mbpoll(
      mbpoll({"-B", "-t", "3:int", "-r", std::to_string(rl::status::kSprayCount), "127.0.0.1"}).output);
  EXPECT_EQ(count.at(rl::status::kSprayCount), "1");

  // Outside the workspace: rejected with the workspace bit.
  mbpoll({"-t", "4", "-r", "0", "127.0.0.1", "1", "3", "3", "0", "4000", "0", "20000", "3000", "0", "0"});
  s = status();
  EXPECT_EQ(s[rl::status::kSequence], "3");
  EXPECT_EQ(s[rl::status::kState], std::to_string(static_cast<int>(rl::State::kFault)));
  EXPECT_EQ(s[rl::status::kFaults], std::to_string(rl::fault::kWorkspace));
}

TEST_F(MbpollClient, ReadsTheFloatSpeedAndTheClockInTheDocumentedWordOrder) {
  mbpoll({"-t", "4", "-r", "0", "127.0.0.1", "1", "1", "1", "0", "4000", "6000", "5000", "3000", "0", "0"});
  clock_.sleep_for(1.0);  // 0.6 m at 0.25 m/s: cruising
  const double t0 = clock_.now();
  const auto f = parse_mbpoll(
      mbpoll({"-B", "-t", "3:float", "-r", std::to_string(rl::status::kToolSpeed), "127.0.0.1"}).output);
  const auto ms = parse_mbpoll(
      mbpoll({"-B", "-t", "3:int", "-r", std::to_string(rl::status::kRobotTimeMs), "127.0.0.1"}).output);
  const double t1 = clock_.now();
  EXPECT_NEAR(std::stod(f.at(rl::status::kToolSpeed)), 0.25, 1e-5);
  const double robot_time = std::stod(ms.at(rl::status::kRobotTimeMs)) * 1e-3;
  EXPECT_GE(robot_time, t0 - 0.002);
  EXPECT_LE(robot_time, t1 + 0.002);
}

}  // namespace
}  // namespace dentmark
