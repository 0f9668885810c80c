#include "dentmark/firmware/hal/camera/stereo_pairing.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

namespace dentmark::hal {

StereoPairing::StereoPairing(double max_skew, std::size_t max_queue)
    : max_skew_(max_skew),
      max_queue_(std::max<std::size_t>(1, max_queue)),
      newest_left_(-std::numeric_limits<double>::infinity()),
      newest_right_(-std::numeric_limits<double>::infinity()) {
  if (!(max_skew >= 0.0) || !std::isfinite(max_skew))
    throw CameraError("stereo pairing: max_skew must be >= 0");
}

void StereoPairing::push_left(Frame frame) {
  if (frame.time < newest_left_) {
    ++counters_.dropped_left;
    return;
  }
  newest_left_ = frame.time;
  left_.push_back(std::move(frame));
  match();
}

void StereoPairing::push_right(Frame frame) {
  if (frame.time < newest_right_) {
    ++counters_.dropped_right;
    return;
  }
  newest_right_ = frame.time;
  right_.push_back(std::move(frame));
  match();
}

void StereoPairing::match() {
  while (!left_.empty() && !right_.empty()) {
    const double tl = left_.front().time, tr = right_.front().time;
    if (tl < tr - max_skew_) {  // no later right frame can come closer to it
      left_.pop_front();
      ++counters_.dropped_left;
      continue;
    }
    if (tr < tl - max_skew_) {
      right_.pop_front();
      ++counters_.dropped_right;
      continue;
    }
    // Within the skew. If the other side's next frame is closer still, this one loses.
    if (left_.size() > 1 && std::abs(left_[1].time - tr) < std::abs(tl - tr)) {
      left_.pop_front();
      ++counters_.dropped_left;
      continue;
    }
    if (right_.size() > 1 && std::abs(right_[1].time - tl) < std::abs(tl - tr)) {
      right_.pop_front();
      ++counters_.dropped_right;
      continue;
    }
    StereoPair p;
    p.left = std::move(left_.front());
    p.right = std::move(right_.front());
    left_.pop_front();
    right_.pop_front();
    p.time = 0.5 * (p.left.time + p.right.time);
    p.skew = p.right.time - p.left.time;
    pairs_.push_back(std::move(p));
    ++counters_.pairs;
  }
  // A side whose partner never comes (camera stalled) must not grow without bound.
  while (left_.size() > max_queue_) {
    left_.pop_front();
    ++counters_.dropped_left;
  }
  while (right_.size() > max_queue_) {
    right_.pop_front();
    ++counters_.dropped_right;
  }
}

std::optional<StereoPair> StereoPairing::pop() {
  if (pairs_.empty()) return std::nullopt;
  StereoPair p = std::move(pairs_.front());
  pairs_.pop_front();
  return p;
}

StereoCamera::StereoCamera(Camera& left, Camera& right, double max_skew, clock::Clock& clock)
    : left_(left), right_(right), clock_(clock), pairing_(max_skew) {}

void StereoCamera::start() {
  left_.start();
  right_.start();
}

void StereoCamera::stop() {
  left_.stop();
  right_.stop();
}

std::optional<StereoPair> StereoCamera::grab_pair(double timeout) {
  const double end = clock_.now() + std::max(0.0, timeout);
  for (;;) {
    if (auto p = pairing_.pop()) return p;
    const double left_s = end - clock_.now();
    if (left_s <= 0.0) return std::nullopt;
    // Read the side that lags; a short slice so the other side is not starved.
    const bool take_left = pairing_.newest_left() <= pairing_.newest_right();
    Camera& cam = take_left ? left_ : right_;
    auto f = cam.grab(std::min(left_s, 0.05));
    if (!f) {
      if (cam.exhausted()) return std::nullopt;
      // Nothing from the lagging side in this slice: give the other a turn.
      Camera& other = take_left ? right_ : left_;
      auto g = other.grab(0.0);
      if (g && take_left) pairing_.push_right(std::move(*g));
      if (g && !take_left) pairing_.push_left(std::move(*g));
      continue;
    }
    if (take_left)
      pairing_.push_left(std::move(*f));
    else
      pairing_.push_right(std::move(*f));
  }
}

}  // namespace dentmark::hal
