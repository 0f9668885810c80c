// Simulated GPIO and the safety supervisor in-process: lines by name, edges recorded
// with timestamps, e-stop forcing the valve off within 10 ms, the software watchdog,
// timed pulses.
#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <random>
#include <thread>

#include "dentmark/firmware/hal/gpio/sim_gpio.h"
#include "dentmark/firmware/hal/safety/safety_supervisor.h"

namespace dentmark::hal {
namespace {

board::GpioConfig board_lines() {
  board::GpioConfig g;
  g.sprayer_valve = {"sprayer-valve", false};
  g.estop = {"estop", true};
  g.part_present = {"part-present", false};
  return g;
}

SimGpio make_chip(clock::Clock& c, const std::string& record = "") {
  return SimGpio({"sprayer-valve", "estop", "part-present", "spare"}, c, record);
}

TEST(SimGpio, LinesAreFoundByNameAndRequestedOnce) {
  clock::SimClock c;
  SimGpio chip = make_chip(c);
  auto lines = request_board_lines(chip, board_lines());
  EXPECT_FALSE(lines.sprayer_valve->get());
  EXPECT_THROW(chip.request_output({"sprayer-valve", false}, false), GpioError);  // busy
  try {
    chip.request_input({"no-such-line", false});
    FAIL();
  } catch (const GpioError& e) {
    EXPECT_NE(std::string(e.what()).find("no-such-line"), std::string::npos);
  }
  lines.sprayer_valve.reset();  // released: can be requested again
  EXPECT_NO_THROW(chip.request_output({"sprayer-valve", false}, false));
}

TEST(SimGpio, EveryEdgeIsRecordedWithItsTime) {
  clock::SimClock c(0.0, 10.0);
  char path[] = "/tmp/dentmark-gpio-XXXXXX";
  const int fd = ::mkstemp(path);
  ASSERT_GE(fd, 0);
  ::close(fd);
  {
    SimGpio chip = make_chip(c, path);
    auto valve = chip.request_output({"sprayer-valve", false}, false);
    auto part = chip.request_input({"part-present", false});
    c.advance(0.5);
    valve->set(true);
    valve->set(true);  // no edge
    c.advance(0.25);
    valve->set(false);
    chip.drive("part-present", true);
    const auto ev = part->wait_event(0.0);
    ASSERT_TRUE(ev.has_value());
    EXPECT_TRUE(ev->active);
    EXPECT_DOUBLE_EQ(ev->time, 10.75);
    EXPECT_FALSE(part->wait_event(0.01).has_value());  // one edge, one event
    const auto e = chip.edges();
    ASSERT_EQ(e.size(), 4u);
    EXPECT_EQ(e[0].line, "sprayer-valve");
    EXPECT_FALSE(e[0].active);
    EXPECT_DOUBLE_EQ(e[0].time, 10.0);
    EXPECT_TRUE(e[1].active);
    EXPECT_DOUBLE_EQ(e[1].time, 10.5);
    EXPECT_FALSE(e[2].active);
    EXPECT_DOUBLE_EQ(e[2].time, 10.75);
    EXPECT_EQ(e[3].line, "part-present");
  }
  const auto file = SimGpio::read_record(path);
  ASSERT_EQ(file.size(), 4u);
  EXPECT_NEAR(file[1].time, 10.5, 1e-9);
  EXPECT_TRUE(file[1].active);
  ::unlink(path);
}

TEST(SimGpio, ReleaseAllEndsEveryRequestAsAKilledProcessDoes) {
  clock::SimClock c(0.0, 2.0);
  SimGpio chip = make_chip(c);
  auto valve = chip.request_output({"sprayer-valve", false}, false);
  auto estop = chip.request_input({"estop", true});
  valve->set(true);
  c.advance(0.5);
  chip.release_all();
  EXPECT_FALSE(chip.level("sprayer-valve")) << "a released output falls back to inactive";
  const auto e = chip.edges();
  ASSERT_EQ(e.size(), 3u);
  EXPECT_FALSE(e[2].active);
  EXPECT_DOUBLE_EQ(e[2].time, 2.5);
  // The old handles act no more: the valve stays closed, the e-stop's edges go to the new request.
  valve->set(true);
  valve->force_inactive();
  EXPECT_FALSE(chip.level("sprayer-valve"));
  EXPECT_EQ(chip.edges().size(), 3u);
  auto valve2 = chip.request_output({"sprayer-valve", false}, false);  // free again
  auto estop2 = chip.request_input({"estop", true});
  chip.drive("estop", true);
  EXPECT_FALSE(estop->wait_event(0.0).has_value());
  valve.reset();  // the old handle's end does not free the new request
  estop.reset();
  EXPECT_THROW(chip.request_output({"sprayer-valve", false}, false), GpioError);
  valve2->set(true);
  EXPECT_TRUE(chip.level("sprayer-valve"));
  const auto ev = estop2->wait_event(0.0);
  ASSERT_TRUE(ev.has_value());
  EXPECT_TRUE(ev->active);
}

TEST(SimGpio, BadRecordFileNamesTheLine) {
  char path[] = "/tmp/dentmark-gpio-XXXXXX";
  const int fd = ::mkstemp(path);
  ASSERT_GE(fd, 0);
  const std::string text = "100 valve 1\n200 valve x\n";
  ASSERT_EQ(::write(fd, text.data(), text.size()), static_cast<ssize_t>(text.size()));
  ::close(fd);
  try {
    SimGpio::read_record(path);
    FAIL();
  } catch (const GpioError& e) {
    EXPECT_NE(std::string(e.what()).find(std::string(path) + ":2:"), std::string::npos) << e.what();
  }
  ::unlink(path);
}

TEST(SafetySupervisor, EstopForcesTheValveOffWithin10ms) {
  clock::MonotonicClock c;
  SimGpio chip = make_chip(c);
  auto lines = request_board_lines(chip, board_lines());
  SafetySupervisor safety(std::move(lines.sprayer_valve), std::move(lines.estop), c, {10.0, 0.05});
  ASSERT_TRUE(safety.open_valve());
  ASSERT_TRUE(chip.level("sprayer-valve"));
  std::this_thread::sleep_for(std::chrono::milliseconds(20));  // the supervisor is waiting for an edge
  chip.drive("estop", true);
  const double deadline = c.now() + 1.0;
  while (chip.level("sprayer-valve") && c.now() < deadline) std::this_thread::yield();
  const auto e = chip.edges();
  double t_estop = -1, t_off = -1;
  for (const auto& r : e) {
    if (r.line == "estop" && r.active) t_estop = r.time;
    if (r.line == "sprayer-valve" && !r.active && t_estop >= 0) t_off = r.time;
  }
  ASSERT_GE(t_estop, 0);
  ASSERT_GE(t_off, 0) << "valve never closed";
  EXPECT_LT(t_off - t_estop, 0.010);
  EXPECT_EQ(safety.reason(), SafeReason::kEstop);
  EXPECT_FALSE(safety.open_valve());  // latched
  EXPECT_FALSE(safety.reset());       // still pressed
  EXPECT_TRUE(safety.estop_pressed());
  chip.drive("estop", false);
  // Released: the input reads so at once, the latch stays until reset (the daemon
  // refuses a new job only while the input is pressed; the job's arm() resets).
  const double released = c.now() + 1.0;
  while (safety.estop_pressed() && c.now() < released) std::this_thread::yield();
  EXPECT_FALSE(safety.estop_pressed());
  EXPECT_EQ(safety.reason(), SafeReason::kEstop);
  EXPECT_TRUE(safety.reset());
  EXPECT_TRUE(safety.open_valve());
}

TEST(SafetySupervisor, StartsLatchedWhenEstopIsAlreadyPressed) {
  clock::MonotonicClock c;
  SimGpio chip = make_chip(c);
  chip.drive("estop", true);
  auto lines = request_board_lines(chip, board_lines());
  SafetySupervisor safety(std::move(lines.sprayer_valve), std::move(lines.estop), c);
  EXPECT_EQ(safety.reason(), SafeReason::kEstop);
  EXPECT_FALSE(safety.open_valve());
  EXPECT_FALSE(chip.level("sprayer-valve"));
}

TEST(SafetySupervisor, WatchdogClosesTheValveWhenTheLoopStalls) {
  // Rate and timeout leave room for scheduling delays under qemu-user: the watchdog is
  // 0.5 s simulated = 100 ms real, kicks come every 10 ms real.
  clock::SimClock c(5.0);
  SimGpio chip = make_chip(c);
  auto lines = request_board_lines(chip, board_lines());
  SafetySupervisor safety(std::move(lines.sprayer_valve), std::move(lines.estop), c, {0.5, 0.001});
  ASSERT_TRUE(safety.open_valve());
  const double t_open = c.now();
  double last_kick = t_open;
  for (int i = 0; i < 20; ++i) {  // a healthy loop: kicks every 0.05 s for 1 s
    c.sleep_for(0.05);
    // Read before the kick: the scaled clock runs on while the kick is taken, and the
    // watchdog counts from the kick's own time, which is no earlier than this.
    last_kick = c.now();
    safety.kick();
    ASSERT_TRUE(chip.level("sprayer-valve")) << "closed although kicked, at " << c.now() - t_open;
  }
  c.sleep_for(1.0);  // stall
  EXPECT_FALSE(chip.level("sprayer-valve"));
  EXPECT_EQ(safety.reason(), SafeReason::kWatchdog);
  const auto e = chip.edges();
  ASSERT_FALSE(e.empty());
  EXPECT_FALSE(e.back().active);
  EXPECT_GE(e.back().time - last_kick, 0.5);
  EXPECT_LT(e.back().time - last_kick, 0.5 + 0.25);  // 0.25 s simulated = 50 ms real of slack
}

TEST(SafetySupervisor, PulseClosesAfterItsDuration) {
  clock::SimClock c(10.0);
  SimGpio chip = make_chip(c);
  auto lines = request_board_lines(chip, board_lines());
  SafetySupervisor safety(std::move(lines.sprayer_valve), nullptr, c, {100.0, 0.001});
  ASSERT_TRUE(safety.pulse(0.3));
  EXPECT_TRUE(chip.level("sprayer-valve"));
  c.sleep_for(0.6);
  EXPECT_FALSE(chip.level("sprayer-valve"));
  const auto e = chip.edges();
  ASSERT_GE(e.size(), 3u);
  const double width = e[2].time - e[1].time;
  EXPECT_GE(width, 0.3);
  EXPECT_LT(width, 0.3 + 0.1);
}

TEST(SafetySupervisor, DestructorClosesTheValve) {
  clock::MonotonicClock c;
  SimGpio chip = make_chip(c);
  {
    auto lines = request_board_lines(chip, board_lines());
    SafetySupervisor safety(std::move(lines.sprayer_valve), std::move(lines.estop), c, {10.0, 0.01});
    ASSERT_TRUE(safety.open_valve());
  }
  EXPECT_FALSE(chip.level("sprayer-valve"));
}

}  // namespace
}  // namespace dentmark::hal

namespace dentmark::hal {
namespace {

// Property: random bytes in a GPIO record file give records or a GpioError naming
// the file and line, never a crash.
TEST(SimGpio, CorruptedRecordNeverCrashes) {
  char path[] = "/tmp/dentmark-gpio-XXXXXX";
  const int fd = ::mkstemp(path);
  ASSERT_GE(fd, 0);
  ::close(fd);
  std::mt19937 rng(5);
  const std::string alphabet = "0123456789 -\nvalve01x\t";
  for (int trial = 0; trial < 300; ++trial) {
    std::string text = "100 valve 1\n200 valve 0\n";
    for (int e = 0; e < 3; ++e) text[rng() % text.size()] = alphabet[rng() % alphabet.size()];
    std::ofstream(path, std::ios::trunc) << text;
    try {
      for (const auto& r : SimGpio::read_record(path)) ASSERT_FALSE(r.line.empty());
    } catch (const GpioError& e) {
      ASSERT_NE(std::string(e.what()).find(std::string(path) + ":"), std::string::npos) << e.what();
    }
  }
  ::unlink(path);
}

}  // namespace
}  // namespace dentmark::hal
