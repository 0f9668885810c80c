#include "dentmark/firmware/station/tracking_motion_source.h"

#include "dentmark/common/log.h"
#include "dentmark/firmware/track/track_error.h"

namespace dentmark::station {

Transform extrapolate_motion(double t0, const Transform& M0, double t1, const Transform& M1, double t) {
  // The motion from t0 to t1, D = M1 · M0⁻¹, repeated proportionally: rotation vector
  // and translation scale with s = (t − t1)/(t1 − t0). Exact for pure translation,
  // first order for the slow rotations of a conveyor.
  const Transform d = M1 * M0.inverse();
  const double s = (t - t1) / (t1 - t0);
  return make_transform_rotvec(s * rotation_vector(d), s * d.translation()) * M1;
}

TrackingMotionSource::TrackingMotionSource(track::StereoCalibration calibration,
                                           std::vector<cv::Point2f> seeds_right, StereoFrameSource frames,
                                           track::TrackerOptions options)
    : tracker_(std::move(calibration), options), source_(std::move(frames)) {
  const auto first = source_();
  if (!first) throw track::TrackError("tracking: the camera gave no first frame");
  publish(tracker_.start(first->left, first->right, first->t, seeds_right, first->index));
  thread_ = std::thread([this] { run(); });
}

TrackingMotionSource::~TrackingMotionSource() {
  stop();
}

void TrackingMotionSource::stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

void TrackingMotionSource::run() {
  while (!stop_) {
    std::optional<StereoFrame> f;
    try {
      f = source_();
    } catch (const std::exception& e) {
      log::error(std::string("camera: ") + e.what());
      break;
    }
    if (!f) break;
    try {
      publish(tracker_.track(f->left, f->right, f->t, f->index));
    } catch (const std::exception& e) {
      // A bad frame (wrong size, unreadable) is predicted through, not fatal.
      publish(tracker_.skip(f->t, f->index, e.what()));
    }
  }
  ended_ = true;
}

void TrackingMotionSource::publish(const track::FrameResult& r) {
  MotionEstimate e;
  e.t = r.t;
  e.M_camL = r.motion;
  e.ok = r.ok;
  e.quality = r.quality;
  e.features = r.features;
  e.rms = r.rms;
  std::lock_guard lock(mutex_);
  latest_ = e;
  if (r.ok) {
    ++frames_;
    history_.push_back(e);
    while (history_.size() > 2 && history_.back().t - history_.front().t > 3.0) history_.pop_front();
  } else {
    ++failed_;
  }
}

std::optional<MotionEstimate> TrackingMotionSource::latest() {
  std::lock_guard lock(mutex_);
  return latest_;
}

Transform TrackingMotionSource::predict(double t) {
  std::lock_guard lock(mutex_);
  if (history_.empty()) return latest_ ? latest_->M_camL : Transform::Identity();
  const MotionEstimate& last = history_.back();
  // Velocity over a baseline of about a second: the filtered motion is smooth, and a
  // longer baseline keeps pixel noise out of the extrapolation.
  const MotionEstimate* base = nullptr;
  for (const MotionEstimate& e : history_)
    if (last.t - e.t >= 0.3 && last.t - e.t <= 1.5) {
      base = &e;
      break;
    }
  if (!base) return last.M_camL;
  // Before the history, interpolate between its two ends.
  return extrapolate_motion(base->t, base->M_camL, last.t, last.M_camL, t);
}

}  // namespace dentmark::station
