#pragma once
// Stand-ins for the station's tests: a robot that moves on the simulated clock and
// mirrors commands as state (recording where it sprayed), a sprayer valve, and a
// motion source that knows the true motion (the panel translates along camL x).

#include <cmath>
#include <vector>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/plan/marking_pose.h"
#include "dentmark/firmware/station/job_runner.h"

namespace dentmark::station::testing {

class MockRobot final : public hal::Robot {
 public:
  MockRobot(clock::Clock& clock, plan::RobotLimits limits) : clock_(clock), limits_(limits) {
    pose_.translation() = Eigen::Vector3d(0.3, 0.0, 0.4);
  }
  void connect() override { connected_ = true; }
  void disconnect() override { connected_ = false; }
  bool connected() const override { return connected_; }
  std::uint16_t move_to(const Transform& T, double) override {
    update();
    from_ = pose_;
    target_ = T;
    t_start_ = clock_.now();
    if (first_move_at < 0.0) first_move_at = t_start_;
    t_end_ = t_start_ + plan::move_time((T.translation() - pose_.translation()).norm(), limits_);
    state_ = robot_link::State::kMoving;
    return ++seq_;
  }
  std::uint16_t spray(double duration) override {
    update();
    sprays.push_back({clock_.now(), pose_});
    t_end_ = clock_.now() + duration;
    state_ = robot_link::State::kSpraying;
    return ++seq_;
  }
  std::uint16_t abort() override {
    ++aborts;
    aborted_at = clock_.now();
    state_ = robot_link::State::kStopped;
    return ++seq_;
  }
  std::uint16_t reset() override {
    state_ = robot_link::State::kIdle;
    return ++seq_;
  }
  void heartbeat() override {}
  hal::RobotStatus status() override {
    update();
    hal::RobotStatus s;
    s.sequence = seq_;
    s.state = state_;
    s.T_base_tool = pose_;
    return s;
  }
  double first_move_at = -1.0;  // s, when the first move was commanded
  struct Spray {
    double t;
    Transform pose;
  };
  std::vector<Spray> sprays;
  int aborts = 0;
  double aborted_at = -1.0;  // clock time of the last abort

 private:
  void update() {
    if (state_ == robot_link::State::kMoving) {
      const double now = clock_.now();
      const double f = t_end_ > t_start_ ? std::min(1.0, (now - t_start_) / (t_end_ - t_start_)) : 1.0;
      pose_ = target_;
      pose_.translation() = from_.translation() + f * (target_.translation() - from_.translation());
      if (f >= 1.0) state_ = robot_link::State::kIdle;
    } else if (state_ == robot_link::State::kSpraying && clock_.now() >= t_end_) {
      state_ = robot_link::State::kIdle;
    }
  }
  clock::Clock& clock_;
  plan::RobotLimits limits_;
  bool connected_ = false;
  Transform pose_ = Transform::Identity(), from_ = Transform::Identity(), target_ = Transform::Identity();
  double t_start_ = 0, t_end_ = 0;
  std::uint16_t seq_ = 0;
  robot_link::State state_ = robot_link::State::kIdle;
};

class MockSafety final : public SafetyIo {
 public:
  explicit MockSafety(clock::Clock& clock) : clock_(clock) {}
  bool estop_active() override { return estop_after >= 0 && clock_.now() >= estop_after; }
  bool spray(double duration, const std::function<void()>& watch) override {
    valve_open = true;
    pulses++;
    const double end = clock_.now() + duration;
    try {
      while (clock_.now() < end) {
        if (watch) watch();
        clock_.sleep_for(std::min(0.01, end - clock_.now()));
      }
    } catch (...) {
      valve_open = false;
      cut_at = clock_.now();
      throw;
    }
    valve_open = false;
    return true;
  }
  void valve_off() noexcept override {
    valve_open = false;
    offs++;
  }
  double estop_after = -1.0;
  double cut_at = -1.0;  // s, when a pulse was cut short
  bool valve_open = false;
  int pulses = 0, offs = 0;

 private:
  clock::Clock& clock_;
};

// The panel translates along camL x at the line speed; tracking can drop out.
class LineMotion final : public MotionSource {
 public:
  LineMotion(clock::Clock& clock, double speed) : clock_(clock), speed_(speed) {}
  std::optional<MotionEstimate> latest() override {
    MotionEstimate e;
    e.t = clock_.now() < caught_up_at ? behind_at : clock_.now();
    e.M_camL = predict(e.t);
    e.ok = !(lost_from >= 0 && e.t >= lost_from);
    const bool poor = e.t >= poor_from && e.t < poor_until;
    e.quality = !e.ok ? 0.0 : poor ? 0.05 : 1.0;
    e.expected_error = expected_error;
    e.features = 10;
    return e;
  }
  Transform predict(double t) override {
    Transform m = Transform::Identity();
    m.translation() = Eigen::Vector3d(speed_ * t, 0, 0);
    return m;
  }
  std::optional<std::string> failure() const override {
    if (failed_from >= 0 && clock_.now() >= failed_from) return "cameras dead";
    return std::nullopt;
  }
  double lost_from = -1.0;       // s: estimates not ok from then on (panel out of view)
  double failed_from = -1.0;     // s: no estimates at all from then on (cameras dead)
  double caught_up_at = -1.0;    // s: before then the newest estimate is of the pair at
  double behind_at = 0.0;        //    behind_at (the tracker catching up on kept pairs)
  double poor_from = -1.0;       // s: estimates of poor quality (a bad pair, an occlusion)
  double poor_until = -1.0;      //    from poor_from until poor_until
  double expected_error = 2e-4;  // m, what the tracker reports

 private:
  clock::Clock& clock_;
  double speed_;
};

}  // namespace dentmark::station::testing
