#include "dentmark/firmware/track/replay.h"

#include <cmath>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "dentmark/common/atomic_file.h"
#include "dentmark/common/log.h"
#include "dentmark/firmware/track/model_search.h"
#include "dentmark/firmware/track/sequence.h"
#include "dentmark/firmware/track/track_error.h"

namespace dentmark::track {
namespace fs = std::filesystem;

namespace {

// Frames after the first through the started tracker; unreadable ones are predicted through.
void track_rest(const Sequence& seq, Tracker& tracker, ReplayResult& out, std::size_t until) {
  for (std::size_t k = 1; k < until; ++k) {
    const FrameEntry& f = seq.frames[k];
    cv::Mat l, r;
    try {
      l = load_grey(f.left, seq.calibration.size);
      r = load_grey(f.right, seq.calibration.size);
    } catch (const TrackError& e) {
      log::warn(std::string("frame ") + std::to_string(f.index) + ": " + e.what());
      out.frames.push_back(tracker.skip(f.t, f.index, e.what()));
      continue;
    }
    out.frames.push_back(tracker.track(l, r, f.t, f.index));
  }
}

}  // namespace

ReplayResult replay_sequence(const fs::path& dir, const TrackerOptions& options) {
  const Sequence seq = load_sequence(dir);
  const std::vector<cv::Point2f> seeds = load_seeds(dir / "seeds.yaml", seq.calibration.size);
  Tracker tracker(seq.calibration, options);
  ReplayResult out;
  const FrameEntry& f0 = seq.frames.front();
  const cv::Mat l0 = load_grey(f0.left, seq.calibration.size), r0 = load_grey(f0.right, seq.calibration.size);
  try {
    out.frames.push_back(tracker.start(l0, r0, f0.t, seeds, f0.index));
  } catch (const TrackError& e) {
    throw TrackError((dir / "seeds.yaml").string() + ": " + e.what());
  }
  out.reference_features = static_cast<int>(tracker.reference().size());
  track_rest(seq, tracker, out, seq.frames.size());
  return out;
}

ReplayResult replay_sequence_with_model(const fs::path& dir, const fs::path& model_path,
                                        const TrackerOptions& options) {
  const Sequence seq = load_sequence(dir);
  const PanelModel model = load_panel_model(model_path, seq.calibration.size);
  const FrameEntry& f0 = seq.frames.front();
  const cv::Mat l0 = load_grey(f0.left, seq.calibration.size), r0 = load_grey(f0.right, seq.calibration.size);
  std::vector<cv::Point2f> seeds;
  try {
    const ModelSearchResult found = search_model(seq.calibration, l0, r0, model);
    for (const auto& s : found.seeds_right)
      if (s) seeds.push_back(*s);
    log::info("panel model " + model_path.string() + ": " + std::to_string(found.found) + " of " +
              std::to_string(model.features.size()) + " features found in the first frame");
  } catch (const TrackError& e) {
    throw TrackError(f0.right.string() + ": " + e.what() + " (model " + model_path.string() + ")");
  }
  Tracker tracker(seq.calibration, options);
  ReplayResult out;
  try {
    out.frames.push_back(tracker.start(l0, r0, f0.t, seeds, f0.index));
  } catch (const TrackError& e) {
    throw TrackError(f0.right.string() +
                     ": the panel model's features did not start the tracker: " + e.what());
  }
  out.reference_features = static_cast<int>(tracker.reference().size());
  track_rest(seq, tracker, out, seq.frames.size());
  return out;
}

PanelModel teach_sequence(const fs::path& dir, long index, const fs::path& seeds_path,
                          const TrackerOptions& options) {
  const Sequence seq = load_sequence(dir);
  const fs::path seeds_file = seeds_path.empty() ? dir / "seeds.yaml" : seeds_path;
  const std::vector<cv::Point2f> seeds = load_seeds(seeds_file, seq.calibration.size);
  std::size_t at = 0;
  if (index >= 0) {
    while (at < seq.frames.size() && seq.frames[at].index != index) ++at;
    if (at == seq.frames.size())
      throw TrackError((dir / "frames.csv").string() + ": no frame with index " + std::to_string(index));
  }
  Tracker tracker(seq.calibration, options);
  ReplayResult out;
  const FrameEntry& f0 = seq.frames.front();
  cv::Mat left = load_grey(f0.left, seq.calibration.size), right = load_grey(f0.right, seq.calibration.size);
  try {
    out.frames.push_back(tracker.start(left, right, f0.t, seeds, f0.index));
  } catch (const TrackError& e) {
    throw TrackError(seeds_file.string() + ": " + e.what());
  }
  if (at > 0) {
    // Follow the panel to the teach frame, then start afresh there from where the
    // features are now (refined and triangulated in that frame).
    track_rest(seq, tracker, out, at + 1);
    const FrameEntry& f = seq.frames[at];
    if (!out.frames.back().ok)
      throw TrackError(f.left.string() + ": the tracker lost the panel at the teach frame (" +
                       out.frames.back().note + ")");
    std::vector<cv::Point2f> here;
    for (std::size_t i = 0; i < tracker.reference().size(); ++i)
      if (tracker.tracked()[i]) here.push_back(tracker.right_points()[i]);
    left = load_grey(f.left, seq.calibration.size);
    right = load_grey(f.right, seq.calibration.size);
    try {
      tracker.start(left, right, f.t, here, f.index);
    } catch (const TrackError& e) {
      throw TrackError(f.left.string() + ": " + e.what());
    }
  }
  return make_panel_model(left, right, tracker.reference().points(), tracker.left_points(),
                          tracker.right_points());
}

void write_replay_json(const ReplayResult& result, const fs::path& path) {
  nlohmann::json frames = nlohmann::json::array();
  for (const FrameResult& f : result.frames) {
    nlohmann::json m = nlohmann::json::array();
    for (int r = 0; r < 4; ++r) {
      nlohmann::json row = nlohmann::json::array();
      for (int c = 0; c < 4; ++c) row.push_back(f.motion.matrix()(r, c));
      m.push_back(row);
    }
    nlohmann::json j = {{"index", f.index},     {"t", f.t},
                        {"ok", f.ok},           {"features", f.features},
                        {"quality", f.quality}, {"expected_error", f.expected_error},
                        {"rms", f.rms},         {"motion", m}};
    if (!f.note.empty()) j["note"] = f.note;
    frames.push_back(j);
  }
  const nlohmann::json doc = {{"frames", frames}};
  try {
    files::write_atomically(path, doc.dump(1) + "\n");
  } catch (const files::FileError& e) {
    throw TrackError(e.what());
  }
}

namespace {

std::vector<std::vector<double>> read_numeric_csv(const fs::path& path, std::size_t columns) {
  std::ifstream in(path);
  if (!in) throw TrackError(path.string() + ": cannot open");
  std::vector<std::vector<double>> rows;
  std::string line;
  long no = 0;
  while (std::getline(in, line)) {
    ++no;
    if (no == 1 || line.find_first_not_of(" \r\t") == std::string::npos) continue;  // header
    std::vector<double> v;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) {
      char* end = nullptr;
      const double x = std::strtod(cell.c_str(), &end);
      if (end == cell.c_str() || !std::isfinite(x))
        throw TrackError(path.string() + ":" + std::to_string(no) + ": '" + cell + "' is not a number");
      v.push_back(x);
    }
    if (v.size() != columns)
      throw TrackError(path.string() + ":" + std::to_string(no) + ": expected " + std::to_string(columns) +
                       " fields");
    rows.push_back(v);
  }
  return rows;
}

}  // namespace

MotionErrors compare_with_truth(const ReplayResult& result, const fs::path& truth_csv,
                                const fs::path& points_csv, long first_frame, long last_frame) {
  std::map<long, Transform> truth;
  for (const auto& r : read_numeric_csv(truth_csv, 14)) {
    Transform m = Transform::Identity();
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 4; ++j) m.matrix()(i, j) = r[static_cast<std::size_t>(2 + 4 * i + j)];
    truth[static_cast<long>(r[0])] = m;
  }
  std::vector<Eigen::Vector3d> pts;
  for (const auto& r : read_numeric_csv(points_csv, 3)) pts.emplace_back(r[0], r[1], r[2]);
  if (pts.empty()) throw TrackError(points_csv.string() + ": no points");
  MotionErrors e;
  double sum = 0.0, sq = 0.0;
  long count = 0;
  for (const FrameResult& f : result.frames) {
    if ((first_frame >= 0 && f.index < first_frame) || (last_frame >= 0 && f.index > last_frame)) continue;
    const auto it = truth.find(f.index);
    if (it == truth.end()) continue;
    if (!f.ok) {
      ++e.failed;
      continue;
    }
    ++e.frames;
    for (const auto& p : pts) {
      const double d = (f.motion * p - it->second * p).norm();
      sum += d;
      sq += d * d;
      e.worst = std::max(e.worst, d);
      ++count;
    }
  }
  if (count > 0) {
    e.mean = sum / static_cast<double>(count);
    e.rms = std::sqrt(sq / static_cast<double>(count));
  }
  return e;
}

}  // namespace dentmark::track
