#include "dentmark/firmware/station/supervised_safety.h"

#include <algorithm>

namespace dentmark::station {

bool SupervisedSafety::arm() {
  supervisor_.kick();
  // A watchdog latch from the idle time between jobs is cleared; an e-stop still
  // pressed keeps it latched and refuses the job.
  return !supervisor_.latched() || supervisor_.reset();
}

bool SupervisedSafety::spray(double duration, const std::function<void()>& watch) {
  if (!supervisor_.pulse(duration)) return false;
  // The supervisor closes the valve at the end of the pulse; keep the loop alive
  // (watchdog) and watch the robot while it is open.
  const double end = clock_.now() + duration;
  try {
    while (clock_.now() < end) {
      supervisor_.kick();
      if (watch) watch();
      clock_.sleep_for(std::min(0.01, end - clock_.now()));
    }
  } catch (...) {
    valve_off();
    throw;
  }
  return !supervisor_.latched();
}

}  // namespace dentmark::station
