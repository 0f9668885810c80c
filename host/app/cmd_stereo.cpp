// `dentmark synth stereo`: renders a stereo sequence of the moving door with ground truth.
#include <memory>
#include <string>

#include "commands.h"
#include "dentmark/common/log.h"
#include "dentmark/sim/stereo/sequence_writer.h"

namespace dentmark::cli {

void register_stereo(CLI::App& /*app*/, CLI::App& synth) {
  auto opt = std::make_shared<sim::stereo::SequenceOptions>();
  auto out = std::make_shared<std::string>();
  CLI::App* cmd = synth.add_subcommand("stereo", "Render a stereo sequence of the door moving on the line");
  cmd->add_option("--out", *out, "Output directory (must not exist or be empty)")->required();
  cmd->add_option("--seconds", opt->seconds, "Length of the run, s")->capture_default_str();
  cmd->add_option("--fps", opt->fps, "Frame rate, Hz")->capture_default_str();
  cmd->add_option("--width", opt->width, "Image width, px")->capture_default_str();
  cmd->add_option("--height", opt->height, "Image height, px")->capture_default_str();
  cmd->add_option("--focal", opt->focal_px, "Focal length, px")->capture_default_str();
  cmd->add_option("--baseline", opt->baseline, "Stereo baseline, m")->capture_default_str();
  cmd->add_option("--distance", opt->distance, "Distance camL to the door, m")->capture_default_str();
  cmd->add_option("--speed", opt->speed, "Line speed, m/s")->capture_default_str();
  cmd->add_option("--vibration", opt->vibration, "Vibration amplitude, m")->capture_default_str();
  cmd->add_option("--lighting", opt->lighting, "Lighting gain swing (0.3: ±30 %)")->capture_default_str();
  cmd->add_option("--blur", opt->blur_sigma, "Optical blur sigma, px")->capture_default_str();
  cmd->add_option("--noise", opt->noise_sigma, "Sensor noise sigma, grey levels")->capture_default_str();
  cmd->add_option("--seed-error", opt->seed_error, "Seed error, ±px per axis")->capture_default_str();
  cmd->add_option("--k1", opt->k1, "Radial distortion k1 of both cameras")->capture_default_str();
  cmd->add_flag("--occlude", opt->occlude,
                "The robot arm hides 4 of the 10 features from 30 % to 60 % of the run");
  cmd->add_option("--stop-at", opt->stop_at, "The line stops at this time, s")->capture_default_str();
  cmd->add_option("--stop-for", opt->stop_for, "... for this long, s")->capture_default_str();
  cmd->add_flag("--colour", opt->colour, "Write colour (BGR) PNGs");
  cmd->add_option("--start-offset", opt->start_offset,
                  "The run starts this far further along the line than the centred run, m")
      ->capture_default_str();
  cmd->add_option("--extra-yaw", opt->extra_yaw, "The door turned by this much more about camL y, rad")
      ->capture_default_str();
  cmd->add_option("--gain", opt->gain, "Overall lighting gain (1: as taught)")->capture_default_str();
  cmd->add_flag("--rear-door", opt->rear_door, "Render the rear door (a different panel model)");
  cmd->add_option("--seed", opt->seed, "Random seed")->capture_default_str();
  cmd->callback([opt, out] {
    try {
      sim::stereo::write_sequence(*opt, *out);
      log::info("wrote " + *out);
      exit_code() = 0;
    } catch (const std::exception& e) {
      log::error(e.what());
      exit_code() = 2;
    }
  });
}

}  // namespace dentmark::cli
