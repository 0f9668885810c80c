#pragma once
// The injected clock (design.md §4, §7): everything that waits or timestamps takes a
// Clock&, so the same code runs on the real monotonic clock on the edge box and on a
// simulated clock, faster than real time, in the station's twin and in tests.
//
// Time is in seconds (double) on a monotonic line with an arbitrary origin; a double
// keeps sub-microsecond resolution for more than a year of uptime.

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <thread>
#include <utility>

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
  // Waits on cv, with 'lock' held on entry and on return, until notify_all(cv) or until
  // now() >= t (t may be +infinity). Wake-ups may be spurious: callers loop on their
  // condition. A waiting thread's work holds lapse as in sleep_until().
  virtual void wait_until(std::unique_lock<std::mutex>& lock, std::condition_variable& cv, double t);
  // Wakes every thread waiting on cv, through wait_until() or directly.
  virtual void notify_all(std::condition_variable& cv) { cv.notify_all(); }
  // Holds time still until resume(); any thread may resume. Holds nest. Real clocks
  // ignore them.
  virtual void pause() {}
  virtual void resume() {}
};

// A thread that takes part in simulated time for all its life: it holds the clock
// (begin_work) while it runs, and its hold lapses only while it waits on the clock.
// Time stands still from the constructor until the thread has taken its hold, so a
// thread started at time t acts at t. On a real clock this is a plain thread.
class ParticipantThread {
 public:
  ParticipantThread() = default;
  ParticipantThread(Clock& clock, std::function<void()> body);
  ParticipantThread(ParticipantThread&&) noexcept = default;
  ParticipantThread& operator=(ParticipantThread&& other) noexcept;
  ~ParticipantThread();
  bool joinable() const { return thread_.joinable(); }
  // Waits on the clock for the body to return, then joins: a participant that joins
  // another lets it have its turn instead of holding time still.
  void join();

 private:
  struct Exit {
    std::mutex mutex;
    std::condition_variable done_changed;
    bool done = false;
  };
  Clock* clock_ = nullptr;
  std::shared_ptr<Exit> exit_;
  std::thread thread_;
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
  void pause() override;
  void resume() override;
  // A hold of the calling thread: it lapses while that thread sleeps on this clock and
  // returns when it wakes, so a worker that holds the clock for all its work lets time
  // run only while it waits.
  void begin_work() override;
  void end_work() override;
  // Lapses the calling thread's work holds while it waits, like sleep_until(). Waits in
  // real time (at most 50 ms at a time: time may jump by advance()) and never moves
  // manual time.
  void wait_until(std::unique_lock<std::mutex>& lock, std::condition_variable& cv, double t) override;
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

// Lock-step (discrete-event) simulated time: the twin's clock (docs/station-sim.md).
// Threads that take part in simulated time hold the clock while they run
// (begin_work(), or a ParticipantThread); time stands still while any of them runs or
// while a pause() is held. When none runs, time jumps to the earliest deadline of the
// threads waiting on the clock and wakes that one thread alone; ties go to the thread
// that began waiting first. So exactly one participant runs at a time, in an order fixed
// by simulated time: the same inputs give the same run on any machine and under any
// load, and a run takes only as long as its computation.
// A participant may block on something other than the clock only for what another
// thread gives without simulated time passing (a socket peer's immediate reply).
// Threads that do not take part (network servers, the host side) may sleep on the
// clock too; they are woken as time passes and run beside the participants.
class LockstepClock final : public Clock {
 public:
  // Starts held (one pause()) at 'start': the scene is set up before time runs.
  explicit LockstepClock(double start = 0.0);
  double now() const override;
  void sleep_until(double t) override;
  void wait_until(std::unique_lock<std::mutex>& lock, std::condition_variable& cv, double t) override;
  void notify_all(std::condition_variable& cv) override;
  void begin_work() override;
  void end_work() override;
  void pause() override;
  void resume() override;
  // Moves time forward by dt >= 0 (the next dispatch wakes whoever is then due).
  void advance(double dt);
  // How many times time has moved to a waiting thread's deadline (diagnostics).
  std::uint64_t dispatches() const;
  // How many threads wait on the clock now (diagnostics).
  std::size_t waiting() const;

 private:
  struct Waiter {
    bool participant;
    const std::condition_variable* cv;
    bool woken = false;
  };
  using Key = std::pair<double, std::uint64_t>;  // deadline, then order of arrival
  // Blocks the calling thread until a dispatch wakes it; 'lock' holds mutex_, and
  // 'user' (if any) is let go once the thread is registered.
  void wait_turn(std::unique_lock<std::mutex>& lock, double t, const std::condition_variable* cv,
                 std::unique_lock<std::mutex>* user);
  void dispatch_locked();
  double now_;
  int running_ = 1;  // participants running, plus pauses
  std::uint64_t arrivals_ = 0;
  std::uint64_t dispatches_ = 0;
  std::map<Key, Waiter*> waiting_;
  mutable std::mutex mutex_;
  std::condition_variable turn_;
};

// The process-wide real clock, for code that is handed no clock of its own.
Clock& monotonic_clock();

}  // namespace dentmark::clock
