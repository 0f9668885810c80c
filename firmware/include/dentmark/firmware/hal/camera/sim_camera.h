#pragma once
// A simulated camera: frames at a fixed rate on the injected clock, each rendered by
// a callback for its capture time (the station's twin plugs in the stereo renderer,
// sim/stereo; tests plug in anything). A constant time offset models a sensor that is
// not triggered together with its partner. Frame k is captured at offset + k * period
// on the clock; its sequence number is k.

#include <functional>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/hal/camera/camera.h"

namespace dentmark::hal {

class SimCamera final : public Camera {
 public:
  using Render = std::function<cv::Mat(double time)>;
  // period > 0 (s); offset: added to every capture time (s); frames: 0 = endless.
  SimCamera(std::string name, cv::Size size, double period, Render render, clock::Clock& clock,
            double offset = 0.0, std::uint64_t frames = 0);
  void start() override;
  void stop() override { started_ = false; }
  std::optional<Frame> grab(double timeout) override;
  bool exhausted() const override { return frames_ != 0 && next_ - first_ >= frames_; }
  cv::Size size() const override { return size_; }
  const std::string& name() const override { return name_; }

 private:
  std::string name_;
  cv::Size size_;
  double period_;
  Render render_;
  clock::Clock& clock_;
  double offset_;
  std::uint64_t frames_;
  std::uint64_t first_ = 0;  // grid index of the first frame after start()
  std::uint64_t next_ = 0;   // grid index of the next frame (its sequence number)
  bool started_ = false;
};

}  // namespace dentmark::hal
