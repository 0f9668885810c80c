#pragma once
// The daemon's PanelTracking: the stereo cameras stream all the time; a capture thread
// pairs their frames and keeps a short history, so that a job can start tracking at the
// scan's own instant even when its list arrives after the panel has moved on.
//
// start(list, t_scan):
//   1. the panel model taught for list.panel_id (<models_dir>/<panel_id>.yaml, written
//      by `dentmark-edge teach`) is searched in the kept pair nearest t_scan (model_search.h);
//   2. the tracker starts there, so M(t) is relative to the scan (M(t_scan) = I);
//   3. it is fed the kept pairs after that one, then the newest live pair each time it
//      is ready for one (pairs it had no time for are dropped, as a driver's are).
// History: one pair every `history_period` over the last `history` seconds, plus the
// newest (16 MB per second of history at 1280×1024 and 2 Hz). The panel moves about
// 7 mm (4 px) between kept pairs at the line's 0.014 m/s, well within the tracker's
// pyramidal search.

#include <atomic>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/hal/camera/stereo_pairing.h"
#include "dentmark/firmware/station/station.h"
#include "dentmark/firmware/station/tracking_motion_source.h"
#include "dentmark/firmware/track/model_search.h"
#include "dentmark/firmware/track/stereo_calibration.h"
#include "dentmark/firmware/track/tracker.h"

namespace dentmark::station {

struct CameraTrackingConfig {
  track::StereoCalibration calibration;
  std::filesystem::path models_dir;  // taught panel models: <models_dir>/<panel_id>.yaml
  double history = 10.0;             // s of kept pairs
  double history_period = 0.5;       // s between kept pairs
  double max_scan_gap = 0.3;         // s: the kept pair nearest the scan must be this close
  double max_skew = 0.002;           // s between a pair's left and right exposures
  double grab_timeout = 1.0;         // s (real) without a pair before the cameras count as lost
  // s of simulated time charged per tracked frame (TrackingMotionSource): the twin's
  // model of the target board's tracking time. 0 on a real clock, where it is real.
  double frame_processing_time = 0.0;
  track::TrackerOptions tracker;
  track::ModelSearchOptions search;
  TrackingTrust trust;  // the estimates the prediction is made from (the job's own)
};

class CameraTracking final : public PanelTracking {
 public:
  CameraTracking(hal::Camera& left, hal::Camera& right, clock::Clock& clock, CameraTrackingConfig config);
  ~CameraTracking() override;
  CameraTracking(const CameraTracking&) = delete;
  CameraTracking& operator=(const CameraTracking&) = delete;

  // Starts streaming and the capture thread (throws hal::CameraError).
  void start();
  void stop();

  std::optional<std::string> refuse(const protocol::DefectList& list) override;
  std::unique_ptr<MotionSource> start(const protocol::DefectList& list, double t_scan) override;
  std::uint32_t faults() const override;

  std::filesystem::path model_path(const std::string& panel_id) const;
  long pairs_captured() const { return captured_.load(); }

 private:
  struct Feed;
  void capture_loop();
  void deliver(const StereoFrame& f);

  hal::StereoCamera stereo_;
  clock::Clock& clock_;
  CameraTrackingConfig config_;
  clock::ParticipantThread thread_;  // takes part in simulated time (clock.h)
  std::atomic<bool> stop_{false};
  std::atomic<bool> lost_{false};
  std::atomic<long> captured_{0};
  mutable std::mutex mutex_;
  std::condition_variable first_pair_;
  std::deque<StereoFrame> kept_;  // oldest first
  std::vector<std::weak_ptr<Feed>> feeds_;
};

}  // namespace dentmark::station
