#pragma once
// SafetyIo over the hal's SafetySupervisor: the valve and e-stop lines of the board
// (libgpiod or simulated), with the supervisor's e-stop latch and software watchdog.

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/hal/safety/safety_supervisor.h"
#include "dentmark/firmware/station/job_runner.h"

namespace dentmark::station {

class SupervisedSafety final : public SafetyIo {
 public:
  SupervisedSafety(hal::SafetySupervisor& supervisor, clock::Clock& clock)
      : supervisor_(supervisor), clock_(clock) {}
  bool estop_active() override { return supervisor_.reason() == hal::SafeReason::kEstop; }
  bool estop_pressed() override { return supervisor_.estop_pressed(); }
  bool arm() override;
  void kick() override { supervisor_.kick(); }
  bool spray(double duration, const std::function<void()>& watch) override;
  void valve_off() noexcept override { supervisor_.close_valve(); }

 private:
  hal::SafetySupervisor& supervisor_;
  clock::Clock& clock_;
};

}  // namespace dentmark::station
