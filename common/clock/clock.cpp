#include "dentmark/common/clock/clock.h"

#include <time.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <limits>
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

// The work holds each thread has on each clock (a thread works with one or two clocks).
int& work_holds(const Clock* clock) {
  thread_local std::vector<std::pair<const Clock*, int>> holds;
  for (auto& [c, n] : holds)
    if (c == clock) return n;
  holds.emplace_back(clock, 0);
  return holds.back().second;
}

}  // namespace

void Clock::wait_until(std::unique_lock<std::mutex>& lock, std::condition_variable& cv, double t) {
  const double left = t - now();
  if (left <= 0.0) return;
  if (std::isfinite(left))
    cv.wait_for(lock, std::chrono::duration<double>(to_real(left)));
  else
    cv.wait(lock);
}

ParticipantThread::ParticipantThread(Clock& clock, std::function<void()> body)
    : clock_(&clock), exit_(std::make_shared<Exit>()) {
  clock.pause();
  thread_ = std::thread([&clock, exit = exit_, body = std::move(body)] {
    clock.begin_work();
    clock.resume();
    body();
    {
      std::lock_guard<std::mutex> lock(exit->mutex);
      exit->done = true;
    }
    clock.notify_all(exit->done_changed);
    clock.end_work();
  });
}

ParticipantThread& ParticipantThread::operator=(ParticipantThread&& other) noexcept {
  if (this != &other) {
    join();
    clock_ = other.clock_;
    exit_ = std::move(other.exit_);
    thread_ = std::move(other.thread_);
  }
  return *this;
}

ParticipantThread::~ParticipantThread() {
  join();
}

void ParticipantThread::join() {
  if (!thread_.joinable()) return;
  {
    std::unique_lock<std::mutex> lock(exit_->mutex);
    while (!exit_->done)
      clock_->wait_until(lock, exit_->done_changed, std::numeric_limits<double>::infinity());
  }
  thread_.join();
}

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

void SimClock::wait_until(std::unique_lock<std::mutex>& lock, std::condition_variable& cv, double t) {
  const double left = t - now();
  if (left <= 0.0) return;
  int& mine = work_holds(this);
  const int held = mine;
  for (; mine > 0; --mine) resume();
  const double real = std::isfinite(left) ? std::min(to_real(left), 0.05) : 0.05;
  cv.wait_for(lock, std::chrono::duration<double>(real));
  for (; mine < held; ++mine) pause();
}

double SimClock::to_real(double dt) const {
  return rate_ > 0.0 ? dt / rate_ : dt;
}

LockstepClock::LockstepClock(double start) : now_(start) {
  if (!std::isfinite(start)) throw std::invalid_argument("LockstepClock: start is not finite");
}

double LockstepClock::now() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return now_;
}

std::uint64_t LockstepClock::dispatches() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return dispatches_;
}

std::size_t LockstepClock::waiting() const {
  std::lock_guard lock(mutex_);
  return waiting_.size();
}

void LockstepClock::dispatch_locked() {
  bool woke = false;
  while (running_ == 0 && !waiting_.empty()) {
    const auto first = waiting_.begin();
    const double t = first->first.first;
    if (!std::isfinite(t)) break;  // everyone left waits for an event: time stands still
    Waiter* w = first->second;
    waiting_.erase(first);
    if (t > now_) {
      now_ = t;
      ++dispatches_;
    }
    w->woken = true;
    woke = true;
    if (w->participant) ++running_;
  }
  if (woke) turn_.notify_all();
}

void LockstepClock::wait_turn(std::unique_lock<std::mutex>& lock, double t, const std::condition_variable* cv,
                              std::unique_lock<std::mutex>* user) {
  Waiter w{work_holds(this) > 0, cv};
  waiting_.emplace(Key{t, arrivals_++}, &w);
  if (w.participant) --running_;
  dispatch_locked();
  // Registered before the caller's lock is let go: a notify_all() after the caller
  // checked its condition finds this waiter.
  if (user != nullptr) user->unlock();
  turn_.wait(lock, [&] { return w.woken; });
}

void LockstepClock::sleep_until(double t) {
  if (std::isnan(t)) throw std::invalid_argument("LockstepClock::sleep_until: deadline is NaN");
  std::unique_lock<std::mutex> lock(mutex_);
  if (t <= now_) return;
  wait_turn(lock, t, nullptr, nullptr);
}

void LockstepClock::wait_until(std::unique_lock<std::mutex>& user, std::condition_variable& cv, double t) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (t <= now_) return;
  wait_turn(lock, t, &cv, &user);
  lock.unlock();
  user.lock();
}

void LockstepClock::notify_all(std::condition_variable& cv) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    // Participants waiting on cv are due now, after those already due (arrival order);
    // others wake at once.
    std::vector<Waiter*> due;
    for (auto it = waiting_.begin(); it != waiting_.end();) {
      if (it->second->cv == &cv) {
        due.push_back(it->second);
        it = waiting_.erase(it);
      } else {
        ++it;
      }
    }
    bool woke = false;
    for (Waiter* w : due) {
      if (w->participant) {
        waiting_.emplace(Key{now_, arrivals_++}, w);
      } else {
        w->woken = true;
        woke = true;
      }
    }
    if (woke) turn_.notify_all();
    dispatch_locked();
  }
  cv.notify_all();
}

void LockstepClock::begin_work() {
  if (work_holds(this)++ > 0) return;
  std::lock_guard<std::mutex> lock(mutex_);
  ++running_;
}

void LockstepClock::end_work() {
  int& mine = work_holds(this);
  if (mine == 0 || --mine > 0) return;
  std::lock_guard<std::mutex> lock(mutex_);
  --running_;
  dispatch_locked();
}

void LockstepClock::pause() {
  std::lock_guard<std::mutex> lock(mutex_);
  ++running_;
}

void LockstepClock::resume() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (running_ > 0) --running_;
  dispatch_locked();
}

void LockstepClock::advance(double dt) {
  if (!(dt >= 0.0) || !std::isfinite(dt))
    throw std::invalid_argument("LockstepClock::advance: dt must be finite and >= 0");
  std::lock_guard<std::mutex> lock(mutex_);
  now_ += dt;
  dispatch_locked();
}

Clock& monotonic_clock() {
  static MonotonicClock clock;
  return clock;
}

}  // namespace dentmark::clock
