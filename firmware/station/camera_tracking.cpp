#include "dentmark/firmware/station/camera_tracking.h"

#include <algorithm>
#include <cmath>

#include "dentmark/common/log.h"
#include "dentmark/firmware/track/panel_model.h"
#include "dentmark/firmware/track/track_error.h"

namespace dentmark::station {

// The pairs one tracker is fed: the kept pairs since the scan first, then always the
// newest live pair (one the tracker had no time for is replaced, as a camera driver
// hands out its newest buffer), so the motion estimates stay as fresh as the tracker's
// speed allows.
struct CameraTracking::Feed {
  std::mutex mutex;
  std::condition_variable ready;
  std::deque<StereoFrame> catch_up;
  std::optional<StereoFrame> live;
  double last_t = -1e300;
  bool closed = false;
};

namespace {

// The tracker's motion, failed for as long as the cameras deliver no pairs: a job sees
// a dead camera at its next interlock check, not once the last estimate is too old.
class CameraMotionSource final : public MotionSource {
 public:
  CameraMotionSource(std::unique_ptr<MotionSource> tracker, const std::atomic<bool>& cameras_lost)
      : tracker_(std::move(tracker)), cameras_lost_(cameras_lost) {}
  std::optional<MotionEstimate> latest() override { return tracker_->latest(); }
  Transform predict(double t) override { return tracker_->predict(t); }
  std::optional<std::string> failure() const override {
    if (cameras_lost_) return "the cameras deliver no frames";
    return tracker_->failure();
  }

 private:
  std::unique_ptr<MotionSource> tracker_;
  const std::atomic<bool>& cameras_lost_;
};

}  // namespace

CameraTracking::CameraTracking(hal::Camera& left, hal::Camera& right, clock::Clock& clock,
                               CameraTrackingConfig config)
    : stereo_(left, right, config.max_skew, clock), clock_(clock), config_(std::move(config)) {}

CameraTracking::~CameraTracking() {
  stop();
}

void CameraTracking::start() {
  stereo_.start();
  stop_ = false;
  thread_ = clock::ParticipantThread(clock_, [this] { capture_loop(); });
}

void CameraTracking::stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  stereo_.stop();
  std::lock_guard lock(mutex_);
  for (auto& w : feeds_)
    if (auto f = w.lock()) {
      std::lock_guard fl(f->mutex);
      f->closed = true;
      clock_.notify_all(f->ready);
    }
}

void CameraTracking::capture_loop() {
  long index = 0;
  while (!stop_) {
    std::optional<hal::StereoPair> pair;
    try {
      pair = stereo_.grab_pair(config_.grab_timeout);
    } catch (const std::exception& e) {
      if (!lost_.exchange(true)) log::error(std::string("cameras: ") + e.what());
      clock_.sleep_for(config_.grab_timeout);
      continue;
    }
    if (!pair) {
      if (!lost_.exchange(true)) log::error("cameras: no stereo pair within the grab timeout");
      continue;
    }
    if (lost_.exchange(false)) log::info("cameras: pairs again");
    ++captured_;
    deliver(StereoFrame{pair->left.image, pair->right.image, pair->time, index++});
  }
}

void CameraTracking::deliver(const StereoFrame& f) {
  std::lock_guard lock(mutex_);
  if (kept_.size() < 2 || kept_.back().t - kept_[kept_.size() - 2].t >= config_.history_period)
    kept_.push_back(f);
  else
    kept_.back() = f;  // the newest pair is always kept
  while (!kept_.empty() && kept_.front().t < f.t - config_.history) kept_.pop_front();
  clock_.notify_all(first_pair_);
  feeds_.erase(std::remove_if(feeds_.begin(), feeds_.end(), [](const auto& w) { return w.expired(); }),
               feeds_.end());
  for (auto& w : feeds_) {
    auto feed = w.lock();
    std::lock_guard fl(feed->mutex);
    if (f.t <= feed->last_t) continue;
    feed->live = f;
    feed->last_t = f.t;
    clock_.notify_all(feed->ready);
  }
}

std::filesystem::path CameraTracking::model_path(const std::string& panel_id) const {
  return config_.models_dir / (panel_id + ".yaml");
}

std::optional<std::string> CameraTracking::refuse(const protocol::DefectList& list) {
  if (list.panel_id.empty()) return "the list names no panel model (empty panel_id)";
  if (list.panel_id.find('/') != std::string::npos || list.panel_id.front() == '.')
    return "panel model '" + list.panel_id + "': not a plain name";
  const auto path = model_path(list.panel_id);
  if (!std::filesystem::exists(path))
    return "panel model '" + list.panel_id + "' is unknown: no taught model " + path.string() +
           " (dentmark-edge teach)";
  return std::nullopt;
}

std::uint32_t CameraTracking::faults() const {
  return lost_ ? fault::kCamera : 0u;
}

std::unique_ptr<MotionSource> CameraTracking::start(const protocol::DefectList& list, double t_scan) {
  const track::PanelModel model =
      track::load_panel_model(model_path(list.panel_id), config_.calibration.size);
  auto feed = std::make_shared<Feed>();
  StereoFrame first;
  {
    std::unique_lock lock(mutex_);
    // A list that comes in with its scan needs the pair the cameras are taking now.
    const double deadline = clock_.now() + config_.max_scan_gap + config_.grab_timeout;
    while (!(stop_ || (!kept_.empty() && kept_.back().t >= t_scan)) && clock_.now() < deadline)
      clock_.wait_until(lock, first_pair_, deadline);
    const auto nearest = std::min_element(kept_.begin(), kept_.end(), [&](const auto& a, const auto& b) {
      return std::abs(a.t - t_scan) < std::abs(b.t - t_scan);
    });
    if (nearest == kept_.end() || std::abs(nearest->t - t_scan) > config_.max_scan_gap)
      throw std::runtime_error(
          "no camera pair within " + std::to_string(config_.max_scan_gap) + " s of the scan (" +
          (kept_.empty() ? std::string("no pairs")
                         : "kept pairs span " + std::to_string(clock_.now() - kept_.front().t) + " s back") +
          ")");
    first = *nearest;
    for (auto it = nearest + 1; it != kept_.end(); ++it) feed->catch_up.push_back(*it);
    feed->last_t = kept_.back().t;
    feeds_.push_back(feed);
  }
  std::vector<cv::Point2f> seeds;
  const track::ModelSearchResult found =
      track::search_model(config_.calibration, first.left, first.right, model, config_.search);
  for (const auto& s : found.seeds_right)
    if (s) seeds.push_back(*s);
  log::info("panel model '" + list.panel_id + "': " + std::to_string(found.found) + " of " +
            std::to_string(model.features.size()) + " features found at the scan (" +
            std::to_string(feed->catch_up.size()) + " kept pairs to catch up)");

  bool served_first = false;
  const double timeout = config_.grab_timeout * 2.0;
  StereoFrameSource frames = [feed, first, served_first, timeout,
                              &clock = clock_]() mutable -> std::optional<StereoFrame> {
    if (!served_first) {
      served_first = true;
      return first;
    }
    std::unique_lock lock(feed->mutex);
    if (!feed->catch_up.empty()) {
      StereoFrame f = std::move(feed->catch_up.front());
      feed->catch_up.pop_front();
      return f;
    }
    const double deadline = clock.now() + timeout;
    while (!feed->closed && !feed->live && clock.now() < deadline)
      clock.wait_until(lock, feed->ready, deadline);
    if (!feed->live)
      return std::nullopt;  // cameras lost or stopped: the tracker ends, the job sees tracking lost
    StereoFrame f = std::move(*feed->live);
    feed->live.reset();
    return f;
  };
  return std::make_unique<CameraMotionSource>(
      std::make_unique<TrackingMotionSource>(config_.calibration, seeds, std::move(frames), config_.tracker,
                                             &clock_, config_.frame_processing_time, config_.trust),
      lost_);
}

}  // namespace dentmark::station
