#include "dentmark/firmware/hal/robot/robot.h"

#include <algorithm>
#include <sstream>

namespace dentmark::hal {

RobotStatus Robot::wait_done(std::uint16_t sequence, double timeout, double period, clock::Clock& clock,
                             const std::function<void(const RobotStatus&)>& on_status) {
  const double deadline = clock.now() + timeout;
  for (;;) {
    heartbeat();
    const RobotStatus s = status();
    if (on_status) on_status(s);
    if (s.sequence == sequence) {
      if (s.state == robot_link::State::kIdle) return s;
      if (s.state == robot_link::State::kFault || s.state == robot_link::State::kStopped) {
        std::ostringstream os;
        os << "robot " << (s.state == robot_link::State::kFault ? "rejected" : "stopped") << " command "
           << sequence << ": faults " << robot_link::fault_names(s.faults);
        throw RobotError(
            s.state == robot_link::State::kFault ? RobotError::Kind::kRejected : RobotError::Kind::kStopped,
            os.str());
      }
    }
    const double now = clock.now();
    if (now >= deadline) {
      std::ostringstream os;
      os << "robot command " << sequence << " not done after " << timeout << " s (robot at sequence "
         << s.sequence << ", state " << robot_link::to_string(s.state) << ")";
      throw RobotError(RobotError::Kind::kWaitTimeout, os.str());
    }
    clock.sleep_until(std::min(deadline, now + period));
  }
}

}  // namespace dentmark::hal
