#pragma once
// Keeps the sprayer valve safe (design.md §4 "any fault -> safe: sprayer off").
//
// The valve is off on every exit path:
//  - normal exit and exceptions that unwind: the destructor closes it;
//  - SIGTERM, SIGINT, SIGHUP, SIGQUIT and crashes (SIGSEGV, SIGBUS, SIGFPE, SIGILL,
//    SIGABRT): install_process_guards() adds handlers that close every registered
//    valve with async-signal-safe calls, then re-raise with the default action;
//  - uncaught exceptions: a std::terminate handler closes it, then aborts;
//  - std::exit() without unwinding: an atexit handler closes it;
//  - a stalled control loop: a watchdog thread closes it (and latches) when kick()
//    has not been called for 'watchdog_timeout';
//  - e-stop: the same thread waits on the e-stop line's edge events and closes the
//    valve as soon as the edge arrives (well within 10 ms), latching until reset().
// SIGKILL and power loss cannot be caught: there the valve driver's hardware default
// (normally closed, pulled inactive) is the safety, not this code.
//
// A daemon that handles SIGTERM itself (signalfd, firmware/app/stop_signal.h) blocks
// those signals, so the handler never runs and its normal shutdown path (destructor)
// closes the valve instead.

#include <atomic>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/hal/gpio/gpio.h"

namespace dentmark::hal {

enum class SafeReason { kNone, kEstop, kWatchdog, kRequested };
const char* to_string(SafeReason reason);

struct SafetyOptions {
  double watchdog_timeout = 0.2;  // s of clock time between kick()s before the valve is forced off
  double poll_period = 0.002;     // s (real) the supervisor thread waits for an e-stop edge per turn
};

class SafetySupervisor {
 public:
  // Takes the valve (drives it off at once) and the e-stop input (may be null: no
  // e-stop). If the e-stop is already active, starts latched. The watchdog is armed
  // from construction.
  SafetySupervisor(std::unique_ptr<OutputLine> valve, std::unique_ptr<InputLine> estop, clock::Clock& clock,
                   SafetyOptions options = {});
  ~SafetySupervisor();
  SafetySupervisor(const SafetySupervisor&) = delete;
  SafetySupervisor& operator=(const SafetySupervisor&) = delete;

  // Opens the valve; false (valve stays closed) while latched safe.
  bool open_valve();
  void close_valve();
  // Opens the valve for 'duration' s of clock time; the supervisor thread closes it.
  bool pulse(double duration);
  bool valve_open() const;

  // The control loop calls this every turn; missing it for watchdog_timeout forces safe.
  void kick();
  // Forces the safe state (valve off, latched) from any thread.
  void force_safe(SafeReason reason = SafeReason::kRequested);
  // Clears the latch when the e-stop is released; returns false if it is still pressed.
  bool reset();
  bool latched() const { return reason_.load() != SafeReason::kNone; }
  // The e-stop input as it reads now (a latch from an e-stop outlives its release).
  bool estop_pressed() const { return estop_ && estop_->get(); }
  SafeReason reason() const { return reason_.load(); }
  // Time of the last e-stop activation edge the supervisor acted on, as the input
  // line stamped it (GpiodGpio: the kernel's CLOCK_MONOTONIC event time); < 0 before any.
  double estop_edge_time() const { return estop_edge_time_.load(); }

  // Installs the process-wide signal, terminate and atexit handlers (idempotent).
  static void install_process_guards();
  // Closes every live supervisor's valve; async-signal-safe.
  static void emergency_all_off() noexcept;

 private:
  void run();
  void latch(SafeReason reason);

  std::unique_ptr<OutputLine> valve_;
  std::unique_ptr<InputLine> estop_;
  clock::Clock& clock_;
  SafetyOptions options_;
  std::mutex mutex_;  // serialises valve changes between the control loop and the thread
  std::atomic<SafeReason> reason_{SafeReason::kNone};
  std::atomic<double> last_kick_;
  std::atomic<double> estop_edge_time_{-1.0};
  double pulse_end_ = -1.0;  // clock time to close a pulse; < 0: none (mutex_)
  std::atomic<bool> stop_{false};
  clock::ParticipantThread thread_;  // takes part in simulated time (clock.h)
  std::mutex poll_mutex_;            // the poll's wait on the clock (no e-stop line)
  std::condition_variable poll_;
  int slot_ = -1;  // index in the emergency registry
};

}  // namespace dentmark::hal
