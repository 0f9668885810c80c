// The injected clock: real monotonic time and simulated time (manual and scaled).
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "dentmark/common/clock/clock.h"

using dentmark::clock::MonotonicClock;
using dentmark::clock::SimClock;

TEST(MonotonicClock, SleepsAtLeastUntilTheDeadline) {
  MonotonicClock c;
  const double t0 = c.now();
  c.sleep_until(t0 + 0.02);
  const double t1 = c.now();
  EXPECT_GE(t1 - t0, 0.02);
  EXPECT_LT(t1 - t0, 1.0);  // generous: only catches a clock that runs wild
  c.sleep_until(t0);        // past deadline: returns at once
  EXPECT_LT(c.now() - t1, 0.5);
}

TEST(MonotonicClock, AgreesWithSteadyClock) {
  MonotonicClock c;
  const auto s0 = std::chrono::steady_clock::now();
  const double t0 = c.now();
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  const double dt = c.now() - t0;
  const double ds = std::chrono::duration<double>(std::chrono::steady_clock::now() - s0).count();
  EXPECT_NEAR(dt, ds, 0.01);
}

TEST(SimClock, ManualTimeMovesOnlyWhenTold) {
  SimClock c(0.0, 100.0);
  EXPECT_EQ(c.now(), 100.0);
  std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_EQ(c.now(), 100.0);
  c.advance(0.25);
  EXPECT_EQ(c.now(), 100.25);
  c.sleep_until(103.0);  // jumps, does not block
  EXPECT_EQ(c.now(), 103.0);
  c.sleep_until(50.0);  // never goes back
  EXPECT_EQ(c.now(), 103.0);
  c.sleep_for(1.5);
  EXPECT_EQ(c.now(), 104.5);
  EXPECT_THROW(c.advance(-1.0), std::invalid_argument);
}

TEST(SimClock, ScaledTimeRunsFasterThanReal) {
  SimClock c(50.0);
  MonotonicClock real;
  const double r0 = real.now();
  const double s0 = c.now();
  c.sleep_for(1.0);  // 1 simulated second = 20 ms real
  const double real_dt = real.now() - r0;
  const double sim_dt = c.now() - s0;
  EXPECT_GE(sim_dt, 1.0);
  EXPECT_GE(real_dt, 0.02 * 0.99);
  EXPECT_LT(real_dt, 0.5);
  EXPECT_NEAR(sim_dt / real_dt, 50.0, 50.0 * 0.2);
  EXPECT_DOUBLE_EQ(c.to_real(1.0), 0.02);
}

TEST(SimClock, AdvanceWakesASleeper) {
  SimClock c(0.001);  // nearly frozen: the sleeper would wait ~1000 s of real time
  const double deadline = c.now() + 1.0;
  std::thread sleeper([&] { c.sleep_until(deadline); });
  std::this_thread::sleep_for(std::chrono::milliseconds(10));
  c.advance(2.0);
  sleeper.join();  // hangs (and the test times out) if advance() did not wake it
  EXPECT_GE(c.now(), deadline);
}

TEST(SimClock, PausedTimeStandsStillAndResumeWakesSleepers) {
  SimClock c(100.0);
  c.pause();
  const double t0 = c.now();
  std::atomic<bool> woke{false};
  std::thread sleeper([&] {
    c.sleep_until(t0 + 1.0);  // 10 ms real at this rate, were the clock running
    woke = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(60));
  EXPECT_EQ(c.now(), t0) << "a paused clock does not move";
  EXPECT_FALSE(woke) << "a sleeper does not wake while time stands still";
  c.resume();
  sleeper.join();
  EXPECT_TRUE(woke);
  EXPECT_GE(c.now(), t0 + 1.0);
  EXPECT_LT(c.now(), t0 + 30.0) << "the paused 60 ms did not count (6 s at x100)";
}
