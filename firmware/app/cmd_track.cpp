// `dentmark-edge track`: offline replay through the tracker, started from seeds or a
// taught panel model (cmd_teach.cpp).
#include <chrono>
#include <cstdio>
#include <memory>
#include <sstream>
#include <string>

#include "commands.h"
#include "dentmark/common/log.h"
#include "dentmark/firmware/track/replay.h"
#include "dentmark/firmware/track/track_error.h"

namespace dentmark::edge {
namespace {

struct TrackCliOptions {
  std::string sequence;
  std::string json;
  std::string model;
  bool truth = false;
  bool no_filter = false;
};

int run_track(const TrackCliOptions& o) {
  try {
    track::TrackerOptions options;
    options.filter.enabled = !o.no_filter;
    options.line.enabled = !o.no_filter;
    const auto start = std::chrono::steady_clock::now();
    const track::ReplayResult result = o.model.empty()
                                           ? track::replay_sequence(o.sequence, options)
                                           : track::replay_sequence_with_model(o.sequence, o.model, options);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (!o.json.empty()) track::write_replay_json(result, o.json);
    int ok = 0;
    for (const auto& f : result.frames) ok += f.ok;
    std::ostringstream os;
    os << "track: " << result.frames.size() << " frames, " << ok << " ok, " << result.reference_features
       << " reference features, " << seconds * 1e3 / static_cast<double>(result.frames.size())
       << " ms/frame (with image reading)";
    std::puts(os.str().c_str());
    if (o.truth) {
      const std::filesystem::path dir(o.sequence);
      const auto e = track::compare_with_truth(result, dir / "truth.csv", dir / "eval_points.csv");
      char line[256];
      std::snprintf(
          line, sizeof line,
          "motion error at the evaluation points: mean %.3f mm, rms %.3f mm, worst %.3f mm over %d frames "
          "(%d failed)",
          e.mean * 1e3, e.rms * 1e3, e.worst * 1e3, e.frames, e.failed);
      std::puts(line);
    }
    return 0;
  } catch (const track::TrackError& e) {
    log::error(e.what());
    return 2;
  }
}

}  // namespace

void register_track(CLI::App& app) {
  auto opt = std::make_shared<TrackCliOptions>();
  CLI::App* cmd = app.add_subcommand("track", "Replay a stereo sequence through the panel tracker");
  cmd->add_option("--sequence", opt->sequence, "Sequence directory (stereo.yaml, frames.csv, seeds.yaml)")
      ->required();
  cmd->add_option("--json", opt->json, "Write per-frame motion as JSON");
  cmd->add_option("--model", opt->model, "Acquire this taught panel model instead of using seeds.yaml");
  cmd->add_flag("--truth", opt->truth, "Compare with the directory's truth.csv and eval_points.csv");
  cmd->add_flag("--no-filter", opt->no_filter,
                "Report each frame's own fit (no motion filter, no conveyor line model)");
  cmd->callback([opt] { exit_code() = run_track(*opt); });
}

}  // namespace dentmark::edge
