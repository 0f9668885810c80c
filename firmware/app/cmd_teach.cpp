// `dentmark-edge teach`: stores a panel model (the features' templates and 3D layout)
// so later panels of that model are acquired without seeds (`track --model`).
#include <memory>
#include <string>

#include "commands.h"
#include "dentmark/common/log.h"
#include "dentmark/firmware/track/panel_model.h"
#include "dentmark/firmware/track/replay.h"
#include "dentmark/firmware/track/track_error.h"

namespace dentmark::edge {
namespace {

struct TeachCliOptions {
  std::string sequence;
  std::string seeds;
  std::string out;
  long frame = -1;
};

int run_teach(const TeachCliOptions& o) {
  try {
    const track::PanelModel model = track::teach_sequence(o.sequence, o.frame, o.seeds);
    track::save_panel_model(model, o.out);
    log::info("taught " + std::to_string(model.features.size()) + " features into " + o.out);
    return 0;
  } catch (const track::TrackError& e) {
    log::error(e.what());
    return 2;
  }
}

}  // namespace

void register_teach(CLI::App& app) {
  auto opt = std::make_shared<TeachCliOptions>();
  CLI::App* cmd =
      app.add_subcommand("teach", "Teach a panel model (feature templates and layout) from a sequence");
  cmd->add_option("--sequence", opt->sequence, "Sequence directory (stereo.yaml, frames.csv, seeds.yaml)")
      ->required();
  cmd->add_option("--frame", opt->frame, "Teach at this frames.csv index (default: the first frame)");
  cmd->add_option("--seeds", opt->seeds, "Seeds of the first frame (default: DIR/seeds.yaml)");
  cmd->add_option("--out", opt->out, "Panel model to write (OpenCV FileStorage YAML)")->required();
  cmd->callback([opt] { exit_code() = run_teach(*opt); });
}

}  // namespace dentmark::edge
