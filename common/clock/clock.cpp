#include "dentmark/common/clock/clock.h"

#include <time.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <utility>
#include <vector>

namespace dentmark::clock {
namespace {

double real_monotonic() {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

}  // namespace

double MonotonicClock::now() const {
  return real_monotonic();
}

void MonotonicClock::sleep_until(double t) {
  if (!std::isfinite(t)) throw std::invalid_argument("MonotonicClock::sleep_until: deadline is not finite");
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(std::floor(t));
  ts.tv_nsec = static_cast<long>((t - std::floor(t)) * 1e9);
  if (ts.tv_nsec >= 1000000000L) ts.tv_nsec = 999999999L;
  // Absolute deadline: a signal interrupting the sleep (EINTR) does not stretch it.
  while (::clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

SimClock::SimClock(double rate, double start, bool paused)
    : rate_(rate), offset_(start), real_start_(real_monotonic()) {
  if (!(rate >= 0.0) || !std::isfinite(rate))
    throw std::invalid_argument("SimClock: rate must be finite and >= 0");
  if (paused && rate > 0.0) holds_ = 1, paused_ = true;
}

double SimClock::now_locked() const {
  return paused_ ? offset_ : offset_ + rate_ * (real_monotonic() - real_start_);
}

void SimClock::pause() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (rate_ == 0.0 || holds_++ > 0) return;  // manual time moves only when told anyway
  offset_ = now_locked();
  paused_ = true;
}

void SimClock::resume() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (holds_ == 0 || --holds_ > 0) return;
    if (!paused_) return;
    real_start_ = real_monotonic();
    paused_ = false;
  }
  changed_.notify_all();
}

double SimClock::now() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return now_locked();
}

void SimClock::advance(double dt) {
  if (!(dt >= 0.0) || !std::isfinite(dt))
    throw std::invalid_argument("SimClock::advance: dt must be finite and >= 0");
  {
    std::lock_guard<std::mutex> lock(mutex_);
    offset_ += dt;
  }
  changed_.notify_all();
}

namespace {

// The work holds each thread has on each clock (a thread works with one or two clocks).
int& work_holds(const SimClock* clock) {
  thread_local std::vector<std::pair<const SimClock*, int>> holds;
  for (auto& [c, n] : holds)
    if (c == clock) return n;
  holds.emplace_back(clock, 0);
  return holds.back().second;
}

}  // namespace

void SimClock::begin_work() {
  ++work_holds(this);
  pause();
}

void SimClock::end_work() {
  int& mine = work_holds(this);
  if (mine == 0) return;
  --mine;
  resume();
}

void SimClock::sleep_until(double t) {
  if (!std::isfinite(t)) throw std::invalid_argument("SimClock::sleep_until: deadline is not finite");
  // This thread's work holds lapse while it sleeps, and return when it wakes.
  int& mine = work_holds(this);
  const int held = mine;
  for (; mine > 0; --mine) resume();
  wait_until(t);
  for (; mine < held; ++mine) pause();
}

void SimClock::wait_until(double t) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (rate_ == 0.0) {
    if (t > offset_) offset_ = t;
    lock.unlock();
    changed_.notify_all();
    return;
  }
  for (;;) {
    const double left = t - now_locked();
    if (left <= 0.0) return;
    // Woken early by advance() or resume(); otherwise the real time the remainder takes
    // at this rate (while paused, until woken).
    if (paused_)
      changed_.wait(lock);
    else
      changed_.wait_for(lock, std::chrono::duration<double>(left / rate_));
  }
}

double SimClock::to_real(double dt) const {
  return rate_ > 0.0 ? dt / rate_ : dt;
}

Clock& monotonic_clock() {
  static MonotonicClock clock;
  return clock;
}

}  // namespace dentmark::clock
