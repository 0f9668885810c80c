#pragma once
// Offline replay of a sequence directory through the tracker (`dentmark-edge track`),
// the JSON result, and its comparison against ground truth.

#include <filesystem>
#include <vector>

#include "dentmark/firmware/track/panel_model.h"
#include "dentmark/firmware/track/tracker.h"

namespace dentmark::track {

struct ReplayResult {
  std::vector<FrameResult> frames;
  int reference_features = 0;
};

// Throws TrackError on unreadable stereo.yaml / frames.csv / seeds.yaml, a bad first
// frame, or too few usable features. Later unreadable frames become ok = false.
ReplayResult replay_sequence(const std::filesystem::path& dir, const TrackerOptions& options = {});

// The same without seeds: the panel model (panel_model.h) is acquired in the first
// frame (model_search.h) and its consensus seeds the tracker. Throws TrackError naming
// the model file and field when it is missing, malformed or of another image size, and
// naming the first frame when the model is not found there.
ReplayResult replay_sequence_with_model(const std::filesystem::path& dir, const std::filesystem::path& model,
                                        const TrackerOptions& options = {});

// `dentmark-edge teach`: the panel model of the sequence's panel at frame `index` (the
// frames.csv index; -1: the first frame). The seeds (seeds_right of the first frame,
// default DIR/seeds.yaml) start the tracker at the first frame, which follows the
// panel to the teach frame. Throws TrackError naming the file and field or frame.
PanelModel teach_sequence(const std::filesystem::path& dir, long index = -1,
                          const std::filesystem::path& seeds = {}, const TrackerOptions& options = {});

// {"frames":[{"index","t","ok","features","quality","expected_error","rms","motion":[[4x4]]}]}, written to
// a temporary file then renamed.
void write_replay_json(const ReplayResult& result, const std::filesystem::path& path);

struct MotionErrors {
  int frames = 0;      // frames compared (ok ones present in the truth)
  int failed = 0;      // frames with ok = false
  double mean = 0.0;   // mean over frames and points of |M_est p − M_true p|, m
  double worst = 0.0;  // m
  double rms = 0.0;    // m
};

// truth.csv (index,t,m00..m23) and eval_points.csv (x,y,z, camL at the first frame).
// first_frame/last_frame bound the frame indices compared (inclusive; -1: no bound).
MotionErrors compare_with_truth(const ReplayResult& result, const std::filesystem::path& truth_csv,
                                const std::filesystem::path& points_csv, long first_frame = -1,
                                long last_frame = -1);

}  // namespace dentmark::track
