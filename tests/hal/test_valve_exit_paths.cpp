// The sprayer valve is off after every way a process can end. Each case forks a child
// that opens the valve under a SafetySupervisor with the simulated GPIO backend
// recording every edge to a file, then ends the way the case names; the parent checks
// the file: the valve was opened, and its last recorded level is off.
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <stdexcept>
#include <thread>

#include "dentmark/firmware/hal/gpio/sim_gpio.h"
#include "dentmark/firmware/hal/safety/safety_supervisor.h"

namespace dentmark::hal {
namespace {

enum class Path { kNormal, kUnwind, kUncaught, kExit, kSignal, kCrash, kStall };

constexpr double kWatchdog = 0.3;  // s

[[noreturn]] void throw_through_noexcept() noexcept(false) {
  throw std::runtime_error("control loop failed");
}
void uncaught() noexcept {
  throw_through_noexcept();
}  // leaves a noexcept function: std::terminate

[[noreturn]] void child(Path path, const std::string& record, int ready_fd) {
  rlimit no_core{0, 0};
  ::setrlimit(RLIMIT_CORE, &no_core);  // crashes must not leave core files behind
  SafetySupervisor::install_process_guards();
  clock::MonotonicClock c;
  try {
    SimGpio chip({"sprayer-valve", "estop", "part-present"}, c, record);
    board::GpioConfig g;
    g.sprayer_valve = {"sprayer-valve", false};
    g.estop = {"estop", true};
    g.part_present = {"part-present", false};
    auto lines = request_board_lines(chip, g);
    SafetySupervisor safety(std::move(lines.sprayer_valve), std::move(lines.estop), c, {kWatchdog, 0.002});
    if (!safety.open_valve()) ::_exit(10);
    if (::write(ready_fd, "r", 1) != 1) ::_exit(11);
    switch (path) {
      case Path::kNormal:
        break;
      case Path::kUnwind:
        throw std::runtime_error("job failed");
      case Path::kUncaught:
        uncaught();
        break;
      case Path::kExit:
        std::exit(4);  // no unwinding: the atexit guard must act
      case Path::kCrash:
        ::raise(SIGSEGV);
        break;
      case Path::kSignal:
        for (;;) {  // a healthy loop, waiting to be signalled
          safety.kick();
          std::this_thread::sleep_for(std::chrono::milliseconds(5));
        }
      case Path::kStall:
        for (;;) std::this_thread::sleep_for(std::chrono::seconds(1));  // never kicks again
    }
  } catch (const std::exception&) {
    ::_exit(3);
  }
  ::_exit(0);
}

struct Outcome {
  bool exited = false;
  int code = -1;
  int signal = 0;
  std::vector<EdgeRecord> edges;
};

// Forks the child, waits until the valve is open, optionally signals it, waits
// (bounded) for it to end, and returns how it ended with the valve's recorded edges.
Outcome run_child(Path path, int signal_to_send = 0) {
  char record[] = "/tmp/dentmark-valve-XXXXXX";
  const int fd = ::mkstemp(record);
  EXPECT_GE(fd, 0);
  ::close(fd);
  int ready[2];
  EXPECT_EQ(::pipe(ready), 0);
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(ready[0]);
    child(path, record, ready[1]);
  }
  ::close(ready[1]);
  Outcome out;
  pollfd p{ready[0], POLLIN, 0};
  EXPECT_EQ(::poll(&p, 1, 20000), 1) << "child never opened the valve";
  char c = 0;
  EXPECT_EQ(::read(ready[0], &c, 1), 1);
  ::close(ready[0]);
  if (signal_to_send) ::kill(pid, signal_to_send);
  if (path == Path::kStall) {
    // Wait (bounded) for the watchdog's off edge, then end the stalled child.
    for (int i = 0; i < 400; ++i) {
      const auto e = SimGpio::read_record(record);
      if (!e.empty() && !e.back().active && e.size() >= 3) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    ::kill(pid, SIGKILL);
  }
  int status = 0;
  pid_t r = 0;
  for (int i = 0; i < 2000 && (r = ::waitpid(pid, &status, WNOHANG)) == 0; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  if (r == 0) {
    ::kill(pid, SIGKILL);
    ::waitpid(pid, &status, 0);
    ADD_FAILURE() << "child did not end within 20 s";
  }
  out.exited = WIFEXITED(status);
  out.code = out.exited ? WEXITSTATUS(status) : -1;
  out.signal = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
  for (const auto& e : SimGpio::read_record(record))
    if (e.line == "sprayer-valve") out.edges.push_back(e);
  ::unlink(record);
  return out;
}

// Request (off), open, and at the end off.
void expect_opened_then_off(const Outcome& o) {
  ASSERT_GE(o.edges.size(), 3u);
  EXPECT_FALSE(o.edges[0].active);  // requested closed
  EXPECT_TRUE(o.edges[1].active);   // opened by the child
  EXPECT_FALSE(o.edges.back().active) << "valve left open";
}

TEST(ValveExitPaths, NormalExit) {
  const auto o = run_child(Path::kNormal);
  EXPECT_TRUE(o.exited);
  EXPECT_EQ(o.code, 0);
  expect_opened_then_off(o);
}

TEST(ValveExitPaths, ExceptionUnwinds) {
  const auto o = run_child(Path::kUnwind);
  EXPECT_EQ(o.code, 3);
  expect_opened_then_off(o);
}

TEST(ValveExitPaths, UncaughtExceptionTerminates) {
  const auto o = run_child(Path::kUncaught);
  EXPECT_EQ(o.signal, SIGABRT);
  expect_opened_then_off(o);
}

TEST(ValveExitPaths, ExitWithoutUnwinding) {
  const auto o = run_child(Path::kExit);
  EXPECT_EQ(o.code, 4);
  expect_opened_then_off(o);
}

TEST(ValveExitPaths, Sigterm) {
  const auto o = run_child(Path::kSignal, SIGTERM);
  EXPECT_EQ(o.signal, SIGTERM);
  expect_opened_then_off(o);
}

TEST(ValveExitPaths, Sigint) {
  const auto o = run_child(Path::kSignal, SIGINT);
  EXPECT_EQ(o.signal, SIGINT);
  expect_opened_then_off(o);
}

TEST(ValveExitPaths, Crash) {
  const auto o = run_child(Path::kCrash);
  EXPECT_EQ(o.signal, SIGSEGV);
  expect_opened_then_off(o);
}

TEST(ValveExitPaths, StalledControlLoop) {
  const auto o = run_child(Path::kStall);
  EXPECT_EQ(o.signal, SIGKILL);  // still stalled when we ended it: the valve was closed while it lived
  expect_opened_then_off(o);
  // The watchdog counts from the last kick (construction), before the valve opened
  // (tens of ms before under qemu-user, where starting a thread is slow): the bound
  // that matters for safety is the upper one; the lower one shows it was the watchdog.
  const double open_for = o.edges.back().time - o.edges[1].time;
  EXPECT_GE(open_for, kWatchdog / 2);
  EXPECT_LT(open_for, kWatchdog + 0.2);
}

}  // namespace
}  // namespace dentmark::hal
