// The injected clock: real monotonic time and simulated time (manual and scaled).
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <limits>
#include <mutex>
#include <thread>
#include <vector>

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

// ---- LockstepClock: discrete-event time for the twin ----

using dentmark::clock::LockstepClock;

namespace {

// Three participants with their own periods, one handing work to another through a
// condition variable; returns the log of who ran when.
std::vector<std::pair<int, double>> lockstep_run(bool with_load) {
  LockstepClock clock;
  std::mutex m;
  std::vector<std::pair<int, double>> log;
  const auto note = [&](int who) {
    std::lock_guard lock(m);
    log.emplace_back(who, clock.now());
  };
  std::mutex feed_mutex;
  std::condition_variable feed;
  int queued = 0;
  std::atomic<bool> stop{false};
  std::atomic<bool> spin{with_load};
  std::thread load([&] {
    volatile double x = 0;
    while (spin) x = x + 1.0;
  });
  std::vector<dentmark::clock::ParticipantThread> threads;
  threads.emplace_back(clock, [&] {
    for (int k = 1; k <= 20; ++k) {
      clock.sleep_until(0.1 * k);
      note(1);
      std::lock_guard lock(feed_mutex);
      ++queued;
      clock.notify_all(feed);
    }
  });
  threads.emplace_back(clock, [&] {
    std::unique_lock lock(feed_mutex);
    for (int served = 0; served < 20;) {
      if (queued == 0) {
        clock.wait_until(lock, feed, std::numeric_limits<double>::infinity());
        continue;
      }
      --queued, ++served;
      lock.unlock();
      std::this_thread::sleep_for(std::chrono::microseconds(200));  // work: no time passes
      note(2);
      lock.lock();
    }
  });
  threads.emplace_back(clock, [&] {
    while (clock.now() < 2.0) {
      clock.sleep_for(0.03);
      note(3);
    }
  });
  clock.resume();
  for (auto& t : threads) t.join();
  stop = true;
  spin = false;
  load.join();
  return log;
}

}  // namespace

TEST(LockstepClock, SameRunWhateverTheLoad) {
  const auto quiet = lockstep_run(false);
  ASSERT_EQ(std::count_if(quiet.begin(), quiet.end(), [](const auto& e) { return e.first == 2; }), 20);
  for (int trial = 0; trial < 3; ++trial) EXPECT_EQ(lockstep_run(true), quiet) << "trial " << trial;
}

TEST(LockstepClock, AHandOffRunsBeforeTimeMovesOn) {
  const auto log = lockstep_run(false);
  // Every item the producer queues at t is served at that same t.
  std::vector<double> produced, served;
  for (const auto& [who, t] : log) {
    if (who == 1) produced.push_back(t);
    if (who == 2) served.push_back(t);
  }
  ASSERT_EQ(produced.size(), 20u);
  EXPECT_EQ(served, produced);
  // And events are in time order.
  for (std::size_t i = 1; i < log.size(); ++i) EXPECT_LE(log[i - 1].second, log[i].second);
}

TEST(LockstepClock, TimeStandsStillWhileAParticipantWorksAndJumpsOtherwise) {
  LockstepClock clock(5.0);
  std::atomic<double> seen_after_work{0.0};
  dentmark::clock::ParticipantThread worker(clock, [&] {
    const double t0 = clock.now();
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
    seen_after_work = clock.now() - t0;
    clock.sleep_until(1005.0);  // a thousand simulated seconds
  });
  std::atomic<bool> woke{false};
  std::thread bystander([&] {  // not a participant: woken as time passes
    clock.sleep_until(500.0);
    woke = true;
  });
  const auto r0 = std::chrono::steady_clock::now();
  clock.resume();
  worker.join();
  bystander.join();
  EXPECT_EQ(seen_after_work.load(), 0.0);
  EXPECT_TRUE(woke.load());
  EXPECT_EQ(clock.now(), 1005.0);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - r0).count(), 5.0);
}

TEST(LockstepClock, TiesGoToTheFirstToWait) {
  LockstepClock clock;
  std::mutex m;
  std::vector<int> order;
  std::vector<dentmark::clock::ParticipantThread> ts;
  ts.reserve(4);
  for (int i = 0; i < 4; ++i) {
    ts.emplace_back(clock, [&, i] {
      clock.sleep_until(1.0);
      std::lock_guard lock(m);
      order.push_back(i);
    });
    // Each waits in turn: the next starts once this one is waiting (time is held).
    while (clock.waiting() < static_cast<std::size_t>(i + 1)) std::this_thread::yield();
  }
  clock.resume();
  for (auto& t : ts) t.join();
  EXPECT_EQ(order, (std::vector<int>{0, 1, 2, 3}));
}

TEST(LockstepClock, PauseHoldsTimeAndAdvanceJumps) {
  LockstepClock clock(0.0);  // starts paused
  std::atomic<bool> woke{false};
  dentmark::clock::ParticipantThread p(clock, [&] {
    clock.sleep_until(2.0);
    woke = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_FALSE(woke.load());
  EXPECT_EQ(clock.now(), 0.0);
  clock.advance(1.5);
  EXPECT_EQ(clock.now(), 1.5);
  EXPECT_FALSE(woke.load());
  clock.resume();
  p.join();
  EXPECT_TRUE(woke.load());
  EXPECT_EQ(clock.now(), 2.0);
  EXPECT_THROW(clock.advance(-1.0), std::invalid_argument);
}
