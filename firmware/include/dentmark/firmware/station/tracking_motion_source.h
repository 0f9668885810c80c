#pragma once
// MotionSource over live stereo frames: a thread takes each stereo frame from a frame
// source (hal cameras, replay or the simulator), runs the tracker on it and publishes
// the estimate. Prediction extrapolates the tracker's filtered motion at constant
// velocity (design.md §4: M(t) predicted to the instant the tool arrives).
//
// When tracking falls behind the frame source, frames queue in the source; the source
// decides what to drop (cameras keep only the newest buffers).

#include <atomic>
#include <deque>
#include <functional>
#include <mutex>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/station/motion_source.h"
#include "dentmark/firmware/station/tracking_trust.h"
#include "dentmark/firmware/track/tracker.h"

namespace dentmark::station {

struct StereoFrame {
  cv::Mat left, right;  // 8-bit grey or BGR
  double t = 0.0;       // s, clock time of exposure
  long index = 0;
};

// Returns the next frame, or nullopt when the source has ended (or timed out).
using StereoFrameSource = std::function<std::optional<StereoFrame>()>;

class TrackingMotionSource final : public MotionSource {
 public:
  // Starts the tracker on the source's first frame with rough camR seeds; throws
  // track::TrackError when that fails. Then tracks in a thread until stop().
  // 'clock' (may be null) brackets each frame's tracking with begin_work()/end_work():
  // on the twin's clock tracking then takes no simulated time (clock.h). A modelled
  // 'processing_time' (s, > 0 only on a simulated clock) is charged on the clock instead:
  // each frame's estimate is published that long after the tracker took the frame up.
  // Only estimates 'trust' trusts enter the prediction; latest() gives every one.
  TrackingMotionSource(track::StereoCalibration calibration, std::vector<cv::Point2f> seeds_right,
                       StereoFrameSource frames, track::TrackerOptions options = {},
                       clock::Clock* clock = nullptr, double processing_time = 0.0, TrackingTrust trust = {});
  ~TrackingMotionSource() override;
  TrackingMotionSource(const TrackingMotionSource&) = delete;
  TrackingMotionSource& operator=(const TrackingMotionSource&) = delete;

  std::optional<MotionEstimate> latest() override;
  Transform predict(double t) override;
  // Once the frame source ended or failed (not by stop()): no estimate will come.
  std::optional<std::string> failure() const override;
  void stop();
  long frames_tracked() const { return frames_.load(); }
  long frames_failed() const { return failed_.load(); }  // lost or distrusted

 private:
  void run();
  void end(const std::string& why);  // logs it; failure() reports it from then on
  void publish(const track::FrameResult& r);

  track::Tracker tracker_;
  StereoFrameSource source_;
  clock::Clock* clock_ = nullptr;
  double processing_time_ = 0.0;
  TrackingTrust trust_;
  clock::ParticipantThread thread_;  // takes part in simulated time (clock.h)
  std::atomic<bool> stop_{false};
  std::atomic<long> frames_{0};
  std::atomic<long> failed_{0};
  mutable std::mutex mutex_;
  std::deque<MotionEstimate> history_;  // newest last; trusted estimates of the last few seconds
  // Every trusted estimate's time and motion, oldest first: the past is looked up, never
  // extrapolated (the scan time lies tens of seconds back by the time a job runs).
  std::vector<std::pair<double, Transform>> past_;
  std::optional<MotionEstimate> latest_;
  std::optional<std::string> ended_;
};

// M(t) extrapolated at constant velocity from two motions (t0, M0), (t1, M1), t1 > t0.
Transform extrapolate_motion(double t0, const Transform& M0, double t1, const Transform& M1, double t);

}  // namespace dentmark::station
