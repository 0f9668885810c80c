#include "dentmark/firmware/station/tracking_motion_source.h"

#include <algorithm>
#include <optional>

#include "dentmark/common/log.h"
#include "dentmark/firmware/track/track_error.h"

namespace dentmark::station {
namespace {
constexpr std::size_t kMaxPast = 100000;  // 2.8 h at 10 fps, 14 MB
}  // namespace

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
                                           track::TrackerOptions options, clock::Clock* clock,
                                           double processing_time, TrackingTrust trust)
    : tracker_(std::move(calibration), options),
      source_(std::move(frames)),
      clock_(clock),
      processing_time_(clock != nullptr ? processing_time : 0.0),
      trust_(trust) {
  const auto first = source_();
  if (!first) throw track::TrackError("tracking: the camera gave no first frame");
  publish(tracker_.start(first->left, first->right, first->t, seeds_right, first->index));
  thread_ =
      clock::ParticipantThread(clock_ != nullptr ? *clock_ : clock::monotonic_clock(), [this] { run(); });
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
      end("the frame source failed: " + std::string(e.what()));
      return;
    }
    if (!f) {
      if (!stop_) end("the frame source gave no more pairs");
      return;
    }
    if (clock_) clock_->begin_work();
    const double t_taken = clock_ ? clock_->now() : 0.0;
    track::FrameResult r;
    try {
      r = tracker_.track(f->left, f->right, f->t, f->index);
    } catch (const std::exception& e) {
      // A bad frame (wrong size, unreadable) is predicted through, not fatal.
      r = tracker_.skip(f->t, f->index, e.what());
    }
    if (clock_) clock_->end_work();
    if (processing_time_ > 0.0) clock_->sleep_for(processing_time_);  // the modelled board's time
    if (clock_ && log::level() <= log::Level::kDebug)
      log::debug("tracker: pair " + std::to_string(f->index) + " taken up " + std::to_string(t_taken - f->t) +
                 " s after its exposure, published " + std::to_string(clock_->now() - f->t) +
                 " s after it: " + (r.ok ? "quality " + std::to_string(r.quality) : "lost (" + r.note + ")"));
    publish(r);
  }
}

void TrackingMotionSource::end(const std::string& why) {
  log::error("tracker: " + why + "; no more estimates");
  std::lock_guard lock(mutex_);
  ended_ = "the tracker ended: " + why;
}

std::optional<std::string> TrackingMotionSource::failure() const {
  std::lock_guard lock(mutex_);
  return ended_;
}

void TrackingMotionSource::publish(const track::FrameResult& r) {
  MotionEstimate e;
  e.t = r.t;
  e.M_camL = r.motion;
  e.ok = r.ok;
  e.quality = r.quality;
  e.expected_error = r.expected_error;
  e.features = r.features;
  e.rms = r.rms;
  std::lock_guard lock(mutex_);
  latest_ = e;
  if (!trust_.doubt(e)) {
    ++frames_;
    history_.push_back(e);
    if (past_.size() < kMaxPast) past_.emplace_back(e.t, e.M_camL);
    while (history_.size() > 2 && history_.back().t - history_.front().t > 3.0) history_.pop_front();
  } else {
    ++failed_;
  }
}

std::optional<MotionEstimate> TrackingMotionSource::latest() {
  std::lock_guard lock(mutex_);
  return latest_;
}

namespace {

// Least-squares line through motions (rotation vector and translation of the small
// rigid motion D_i = M_i · M_ref⁻¹ against time), evaluated at t: the intercept smooths
// the reference estimate and the slope is the velocity, both with far less noise than
// a two-point difference. Returns nullopt with fewer than three motions.
template <typename It, typename TimeOf, typename MotionOf>
std::optional<Transform> line_through(It begin, It end, const Transform& M_ref, double t_ref, double t,
                                      TimeOf time_of, MotionOf motion_of) {
  Eigen::Matrix<double, 6, 1> sy = Eigen::Matrix<double, 6, 1>::Zero(), sty = sy;
  double n = 0.0, st = 0.0, stt = 0.0;
  const Transform ref_inv = M_ref.inverse();
  for (It it = begin; it != end; ++it) {
    const double dt = time_of(*it) - t_ref;
    const Transform d = motion_of(*it) * ref_inv;
    Eigen::Matrix<double, 6, 1> y;
    y << rotation_vector(d), d.translation();
    n += 1.0, st += dt, stt += dt * dt;
    sy += y, sty += dt * y;
  }
  const double det = n * stt - st * st;
  if (n < 3.0 || det < 1e-9) return std::nullopt;
  const Eigen::Matrix<double, 6, 1> slope = (n * sty - st * sy) / det;
  const Eigen::Matrix<double, 6, 1> intercept = (sy - slope * st) / n;
  const Eigen::Matrix<double, 6, 1> at = intercept + slope * (t - t_ref);
  return make_transform_rotvec(at.head<3>(), at.tail<3>()) * M_ref;
}

constexpr double kWindow = 1.5;  // s of estimates a line is fitted through

}  // namespace

Transform TrackingMotionSource::predict(double t) {
  std::lock_guard lock(mutex_);
  if (history_.empty()) return latest_ ? latest_->M_camL : Transform::Identity();
  const MotionEstimate& last = history_.back();
  if (!past_.empty() && t < past_.front().first) {
    // Before the first frame tracked (the scan fell between two frames, or before the
    // pair the tracker started on): M is exactly I at that frame by definition, so only
    // the velocity of the line through the first estimates takes it back, not the line's
    // own offset at the frame (the tracker's noise).
    const auto [t0, M0] = past_.front();
    const auto end =
        std::find_if(past_.begin(), past_.end(), [&](const auto& p) { return p.first > t0 + kWindow; });
    const auto time_of = [](const auto& p) { return p.first; };
    const auto motion_of = [](const auto& p) { return p.second; };
    const auto at_t = line_through(past_.begin(), end, M0, t0, t, time_of, motion_of);
    const auto at_t0 = line_through(past_.begin(), end, M0, t0, t0, time_of, motion_of);
    return at_t && at_t0 ? Transform(*at_t * at_t0->inverse() * M0) : M0;
  }
  if (t < last.t - kWindow && !past_.empty()) {
    // Recorded past: interpolate between the two estimates around t.
    const auto it =
        std::lower_bound(past_.begin(), past_.end(), t, [](const auto& p, double x) { return p.first < x; });
    if (it == past_.end()) return past_.back().second;
    if (it == past_.begin()) return it->second;
    const auto& [t1, M1] = *it;
    const auto& [t0, M0] = *(it - 1);
    const double a = t1 > t0 ? (t - t0) / (t1 - t0) : 0.0;
    const Transform d = M1 * M0.inverse();
    return make_transform_rotvec(a * rotation_vector(d), a * d.translation()) * M0;
  }
  // Ahead, or within the recent window: the line through the last kWindow seconds. The
  // window is short enough that a line stop shows within a fraction of a second.
  const auto first_recent = std::find_if(history_.begin(), history_.end(),
                                         [&](const MotionEstimate& e) { return e.t - last.t >= -kWindow; });
  const auto line = line_through(
      first_recent, history_.end(), last.M_camL, last.t, t, [](const MotionEstimate& e) { return e.t; },
      [](const MotionEstimate& e) { return e.M_camL; });
  return line ? *line : last.M_camL;
}

}  // namespace dentmark::station
