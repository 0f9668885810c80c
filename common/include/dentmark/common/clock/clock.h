#pragma once
// The injected clock (design.md §4, §7): everything that waits or timestamps takes a
// Clock&, so the same code runs on the real monotonic clock on the edge box and on a
// simulated clock, faster than real time, in the station's twin and in tests.
//
// Time is in seconds (double) on a monotonic line with an arbitrary origin; a double
// keeps sub-microsecond resolution for more than a year of uptime.

#include <condition_variable>
#include <mutex>

namespace dentmark::clock {

class Clock {
 public:
  virtual ~Clock() = default;
  // Seconds since this clock's origin; never decreases.
  virtual double now() const = 0;
  // Blocks until now() >= t; returns at once when t has passed.
  virtual void sleep_until(double t) = 0;
  void sleep_for(double dt) { sleep_until(now() + dt); }
  // Real (wall) seconds that dt of this clock's time takes. OS-level waits (poll,
  // socket and serial timeouts) are in real time and use this to follow the clock.
  virtual double to_real(double dt) const { return dt; }
  // Bracket computation whose duration is modelled rather than measured on a simulated
  // clock (the twin's rendering and tracking of a frame): a scaled SimClock holds still
  // from begin_work() to end_work(), so what the twin does does not depend on how fast
  // the machine renders and tracks. Real clocks ignore them. Calls nest.
  virtual void begin_work() {}
  virtual void end_work() {}
};

// CLOCK_MONOTONIC: not affected by wall-clock steps (NTP, operator), unlike the
// system clock. Its origin is the kernel's, so timestamps from the kernel (V4L2
// buffers, GPIO line events) are on the same line.
class MonotonicClock final : public Clock {
 public:
  double now() const override;
  void sleep_until(double t) override;
};

// Simulated time. rate > 0: time runs 'rate' simulated seconds per real second (and
// advance() adds jumps); sleepers wake in real time accordingly, so several threads
// can share it. rate == 0 (manual): time moves only by advance(), and sleep_until()
// itself jumps the clock to its deadline (discrete time for single-threaded tests;
// with several threads, each sleeper would move everyone's time).
class SimClock final : public Clock {
 public:
  // paused: the clock starts held at 'start' (one pause(), as if called at once), so
  // that a scene set up before the first resume() sees time exactly at 'start'.
  explicit SimClock(double rate = 0.0, double start = 0.0, bool paused = false);
  double now() const override;
  void sleep_until(double t) override;
  double to_real(double dt) const override;
  // Moves time forward by dt >= 0 and wakes sleepers whose deadline has come.
  void advance(double dt);
  // Holds a scaled clock still until resume() (sleepers keep sleeping): a scene is set
  // up, or a message exchanged, without its real seconds counting as simulated ones.
  // Holds nest: time runs again when every pause() has had its resume(). Any thread may
  // resume another's pause.
  void pause();
  void resume();
  // A hold of the calling thread: it lapses while that thread sleeps on this clock and
  // returns when it wakes, so a worker that holds the clock for all its work lets time
  // run only while it waits.
  void begin_work() override;
  void end_work() override;
  double rate() const { return rate_; }

 private:
  double now_locked() const;
  void wait_until(double t);
  const double rate_;
  double offset_;      // simulated time at real_start_, plus every advance()
  double real_start_;  // real monotonic seconds when the clock was made (or last resumed)
  int holds_ = 0;      // pause()s not yet resumed
  bool paused_ = false;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
};

// The process-wide real clock, for code that is handed no clock of its own.
Clock& monotonic_clock();

}  // namespace dentmark::clock
