#pragma once
// Forms stereo pairs from two free-running (or loosely triggered) cameras by capture
// time: a left and a right frame pair when their times differ by at most max_skew.
// Frames that cannot pair any more are dropped and counted, so a slipping sensor
// shows up in the counters rather than as a silently wrong pair.

#include <deque>
#include <optional>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/hal/camera/camera.h"

namespace dentmark::hal {

struct StereoPair {
  Frame left, right;
  double time = 0.0;  // s, mean of the two capture times
  double skew = 0.0;  // s, right.time - left.time
};

struct PairingCounters {
  long pairs = 0;
  long dropped_left = 0;
  long dropped_right = 0;
};

class StereoPairing {
 public:
  // max_skew >= 0 (s). max_queue: frames kept per side while waiting for a partner.
  explicit StereoPairing(double max_skew, std::size_t max_queue = 8);
  // Frames of each side must come in increasing time (a frame older than the last
  // one of its side is dropped and counted).
  void push_left(Frame frame);
  void push_right(Frame frame);
  // The oldest pair formed so far, if any.
  std::optional<StereoPair> pop();
  const PairingCounters& counters() const { return counters_; }
  // Time of the newest frame of each side (-inf before the first).
  double newest_left() const { return newest_left_; }
  double newest_right() const { return newest_right_; }

 private:
  void match();
  double max_skew_;
  std::size_t max_queue_;
  std::deque<Frame> left_, right_;
  std::deque<StereoPair> pairs_;
  double newest_left_, newest_right_;
  PairingCounters counters_;
};

// Two cameras and a pairing: grab_pair() reads whichever side lags until a pair forms.
class StereoCamera {
 public:
  // 'clock' is the cameras' clock: the timeout runs on it (in the twin, simulated time).
  StereoCamera(Camera& left, Camera& right, double max_skew, clock::Clock& clock);
  void start();
  void stop();
  // The next pair within 'timeout' seconds of the clock, std::nullopt on timeout or when a
  // side is exhausted.
  std::optional<StereoPair> grab_pair(double timeout);
  const PairingCounters& counters() const { return pairing_.counters(); }

 private:
  Camera& left_;
  Camera& right_;
  clock::Clock& clock_;
  StereoPairing pairing_;
};

}  // namespace dentmark::hal
