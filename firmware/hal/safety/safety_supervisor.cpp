#include "dentmark/firmware/hal/safety/safety_supervisor.h"

#include <signal.h>

#include <array>
#include <chrono>
#include <cstdlib>
#include <exception>

namespace dentmark::hal {
namespace {

// Valves reachable from signal handlers: a fixed array of atomic pointers, so the
// handler needs no lock and no allocation.
constexpr int kMaxValves = 8;
std::array<std::atomic<OutputLine*>, kMaxValves> g_valves{};

int register_valve(OutputLine* valve) {
  for (int i = 0; i < kMaxValves; ++i) {
    OutputLine* expected = nullptr;
    if (g_valves[static_cast<std::size_t>(i)].compare_exchange_strong(expected, valve)) return i;
  }
  throw GpioError("safety: more than 8 valves registered");
}

constexpr int kFatalSignals[] = {SIGTERM, SIGINT, SIGHUP, SIGQUIT, SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT};

void on_fatal_signal(int sig) {
  SafetySupervisor::emergency_all_off();
  // Default action (terminate, or core dump for crashes) with the original signal, so
  // the parent sees how we died.
  ::signal(sig, SIG_DFL);
  ::raise(sig);
}

std::terminate_handler g_previous_terminate = nullptr;

void on_terminate() {
  SafetySupervisor::emergency_all_off();
  if (g_previous_terminate) g_previous_terminate();
  std::abort();
}

}  // namespace

const char* to_string(SafeReason reason) {
  switch (reason) {
    case SafeReason::kNone:
      return "none";
    case SafeReason::kEstop:
      return "e-stop";
    case SafeReason::kWatchdog:
      return "watchdog";
    case SafeReason::kRequested:
      return "requested";
  }
  return "?";
}

void SafetySupervisor::emergency_all_off() noexcept {
  for (auto& slot : g_valves)
    if (OutputLine* v = slot.load()) v->force_inactive();
}

void SafetySupervisor::install_process_guards() {
  static std::once_flag once;
  std::call_once(once, [] {
    for (int sig : kFatalSignals) {
      struct sigaction sa {};
      sa.sa_handler = on_fatal_signal;
      sigemptyset(&sa.sa_mask);
      sa.sa_flags = SA_RESETHAND;
      ::sigaction(sig, &sa, nullptr);
    }
    g_previous_terminate = std::set_terminate(on_terminate);
    std::atexit([] { emergency_all_off(); });
  });
}

SafetySupervisor::SafetySupervisor(std::unique_ptr<OutputLine> valve, std::unique_ptr<InputLine> estop,
                                   clock::Clock& clock, SafetyOptions options)
    : valve_(std::move(valve)), estop_(std::move(estop)), clock_(clock), options_(options) {
  if (!valve_) throw GpioError("safety: no valve line");
  if (!(options_.watchdog_timeout > 0.0) || !(options_.poll_period > 0.0))
    throw GpioError("safety: watchdog_timeout and poll_period must be > 0");
  valve_->set(false);
  slot_ = register_valve(valve_.get());
  last_kick_ = clock_.now();
  if (estop_ && estop_->get()) reason_ = SafeReason::kEstop;
  thread_ = clock::ParticipantThread(clock_, [this] { run(); });
}

SafetySupervisor::~SafetySupervisor() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  valve_->set(false);
  g_valves[static_cast<std::size_t>(slot_)].store(nullptr);
}

void SafetySupervisor::latch(SafeReason reason) {
  std::lock_guard<std::mutex> lock(mutex_);
  valve_->set(false);
  pulse_end_ = -1.0;
  SafeReason none = SafeReason::kNone;
  reason_.compare_exchange_strong(none, reason);
}

void SafetySupervisor::force_safe(SafeReason reason) {
  latch(reason);
}

bool SafetySupervisor::open_valve() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (latched()) return false;
  valve_->set(true);
  return true;
}

void SafetySupervisor::close_valve() {
  std::lock_guard<std::mutex> lock(mutex_);
  pulse_end_ = -1.0;
  valve_->set(false);
}

bool SafetySupervisor::pulse(double duration) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (latched() || !(duration > 0.0)) return false;
  valve_->set(true);
  // Deadline after opening: the valve is open for at least 'duration'.
  pulse_end_ = clock_.now() + duration;
  return true;
}

bool SafetySupervisor::valve_open() const {
  return valve_->get();
}

void SafetySupervisor::kick() {
  last_kick_ = clock_.now();
}

bool SafetySupervisor::reset() {
  if (estop_ && estop_->get()) return false;
  reason_ = SafeReason::kNone;
  last_kick_ = clock_.now();
  return true;
}

void SafetySupervisor::run() {
  while (!stop_) {
    if (estop_) {
      // Blocks until an edge or the poll period: the e-stop is handled as the edge
      // arrives, not at the next poll.
      const auto ev = estop_->wait_event(options_.poll_period);
      if (ev && ev->active) {
        estop_edge_time_.store(ev->time);
        latch(SafeReason::kEstop);
      }
    } else {
      std::unique_lock<std::mutex> lock(poll_mutex_);
      clock_.wait_until(lock, poll_, clock_.now() + options_.poll_period);
    }
    const double now = clock_.now();
    if (now - last_kick_.load() > options_.watchdog_timeout && !latched()) latch(SafeReason::kWatchdog);
    std::lock_guard<std::mutex> lock(mutex_);
    if (pulse_end_ >= 0.0 && now >= pulse_end_) {
      valve_->set(false);
      pulse_end_ = -1.0;
    }
  }
}

}  // namespace dentmark::hal
