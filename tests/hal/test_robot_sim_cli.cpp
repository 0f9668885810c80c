// `dentmark robot-sim` as its own process: prints the port it picked, serves our
// Modbus client, and on SIGTERM writes its record (trajectory and sprays) atomically.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>

#include "robot_fixture.h"
#include "subprocess.h"

namespace dentmark {
namespace {

TEST(RobotSimCli, ServesOnAPickedPortAndRecordsOnSigterm) {
  char dir[] = "/tmp/dentmark-robotsim-XXXXXX";
  ASSERT_NE(::mkdtemp(dir), nullptr);
  const std::string record = std::string(dir) + "/record.json";
  int out[2];
  ASSERT_EQ(::pipe2(out, O_CLOEXEC), 0);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, out[1], 1);
  std::vector<std::string> args{DENTMARK_CLI, "robot-sim", "--port",   "0",    "--accuracy",          "0.001",
                                "0",          "0",         "--record", record, "--heartbeat-timeout", "2"};
  auto argv = test::argv_of(args);
  pid_t pid = -1;
  ASSERT_EQ(posix_spawn(&pid, argv[0], &fa, nullptr, argv.data(), environ), 0);
  posix_spawn_file_actions_destroy(&fa);
  ::close(out[1]);
  // First line: "robot-sim listening on 127.0.0.1:<port>".
  std::string line;
  char c;
  pollfd p{out[0], POLLIN, 0};
  while (line.find('\n') == std::string::npos && ::poll(&p, 1, 20000) == 1 && ::read(out[0], &c, 1) == 1)
    line += c;
  ::close(out[0]);
  std::smatch m;
  ASSERT_TRUE(std::regex_search(line, m, std::regex(R"(listening on 127\.0\.0\.1:(\d+))"))) << line;
  const int port = std::stoi(m[1]);

  clock::MonotonicClock clock;
  hal::ModbusRobot robot(test::tcp_config(port), clock);
  robot.connect();
  const auto target = test::pose(0.42, 0.0, 0.5);
  robot.wait_done(robot.move_to(target, 0.0), 10.0, 0.02, clock);
  robot.wait_done(robot.spray(0.02), 10.0, 0.02, clock);

  ::kill(pid, SIGTERM);
  EXPECT_EQ(test::wait_exit(pid, 20.0), 0);
  std::ifstream in(record);
  ASSERT_TRUE(in) << "no record written";
  const auto doc = nlohmann::json::parse(in);
  ASSERT_EQ(doc["sprays"].size(), 1u);
  // The tip was 1 mm off along x (--accuracy): the record holds where it really was.
  EXPECT_NEAR(doc["sprays"][0]["tip"]["t"][0].get<double>(), 0.421, 1e-6);
  EXPECT_NEAR(doc["sprays"][0]["tool"]["t"][0].get<double>(), 0.420, 1e-6);
  EXPECT_GE(doc["trajectory"].size(), 2u);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace dentmark
