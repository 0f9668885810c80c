#include "dentmark/sim/stereo/sequence_writer.h"

#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>

#include "dentmark/common/atomic_file.h"
#include "dentmark/common/image/png_io.h"
#include "dentmark/common/replay_files.h"
#include "dentmark/sim/stereo/panel_motion.h"
#include "dentmark/sim/stereo/stereo_renderer.h"

namespace dentmark::sim::stereo {
namespace fs = std::filesystem;
namespace {

void check_options(const SequenceOptions& o) {
  auto bad = [](const std::string& what) { throw SequenceError("synth stereo: " + what); };
  if (o.width < 64 || o.height < 64 || o.width > 8192 || o.height > 8192)
    bad("image size must be 64..8192 px");
  if (!(o.focal_px > 10.0)) bad("focal length must be > 10 px");
  if (!(o.baseline > 0.0) || !(o.distance > 0.3)) bad("baseline must be > 0 m and distance > 0.3 m");
  if (!(o.seconds >= 0.0) || !(o.fps > 0.0) || o.seconds * o.fps > 100000) bad("need seconds >= 0, fps > 0");
  if (!(o.lighting >= 0.0 && o.lighting < 0.9)) bad("lighting swing must be in [0, 0.9)");
  if (!(o.gain > 0.1 && o.gain < 10.0)) bad("gain must be in (0.1, 10)");
  if (!(std::abs(o.start_offset) < 10.0) || !(std::abs(o.extra_yaw) < 1.0))
    bad("start offset or yaw out of range");
  if (!(o.noise_sigma >= 0.0) || !(o.blur_sigma >= 0.0) || !(o.seed_error >= 0.0))
    bad("negative noise/blur/seed error");
}

void render_into(const SequenceOptions& o, const fs::path& dir) {
  const double toe_in = std::atan(0.5 * o.baseline / o.distance);
  const StereoRig rig = make_rig({o.width, o.height}, o.focal_px, o.baseline, toe_in, o.k1);
  const StereoRenderer renderer(rig, make_door(o.rear_door ? DoorKind::kRear : DoorKind::kFront));
  const DoorModel& door = renderer.door();

  PanelMotion motion;
  motion.speed = o.speed;
  motion.vibration = o.vibration;
  motion.stop_at = o.stop_at;
  motion.stop_for = o.stop_for;
  motion.direction = Eigen::Vector3d(1.0, 0.0, 0.08).normalized();
  const double travel = o.speed * o.seconds;
  Transform pose0 = Transform::Identity();
  pose0.linear() = (Eigen::AngleAxisd(0.12 + o.extra_yaw, Eigen::Vector3d::UnitY()) *
                    Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitX()))
                       .toRotationMatrix();
  // The run is centred where the two views overlap (half a baseline right of camL).
  pose0.translation() =
      Eigen::Vector3d(0.5 * o.baseline, 0.2, o.distance) + (o.start_offset - 0.5 * travel) * motion.direction;
  motion.T_camL_panel0 = pose0;

  write_stereo_yaml(rig, dir / "stereo.yaml");
  fs::create_directories(dir / "left");
  fs::create_directories(dir / "right");

  cv::RNG rng(o.seed);
  {  // Seeds: the right-image corners of frame 0, deliberately a few pixels off.
    std::vector<cv::Point2f> seeds;
    for (const auto& f : door.features) {
      const cv::Point2d p = renderer.project(Eye::kRight, pose0, {f.x(), f.y(), 0.0});
      const auto x = static_cast<float>(p.x + rng.uniform(-o.seed_error, o.seed_error));
      const auto y = static_cast<float>(p.y + rng.uniform(-o.seed_error, o.seed_error));
      seeds.emplace_back(x, y);
    }
    files::write_replay_seeds(dir / "seeds.yaml", seeds);
  }
  files::write_replay_points(dir / "eval_points.csv", pose0, door.lower_panel_points);
  files::write_replay_points(dir / "features.csv", pose0, door.features);

  files::ReplayFrameWriter frames(dir);
  const int n = static_cast<int>(std::floor(o.seconds * o.fps + 1e-9)) + 1;
  for (int k = 0; k < n; ++k) {
    const double t = k / o.fps;
    const Transform pose = motion.T_camL_panel(t);
    RenderConditions c;
    c.gain = o.gain * (1.0 + o.lighting * std::sin(2.0 * std::numbers::pi * t / std::max(o.seconds, 1e-9)));
    c.blur_sigma = o.blur_sigma;
    c.noise_sigma = o.noise_sigma;
    if (o.occlude && t >= 0.3 * o.seconds && t <= 0.6 * o.seconds) {
      // The arm comes down in front of the window frame's left end and moves with the panel.
      Occluder arm;
      arm.a = pose * Eigen::Vector3d(-0.48, 0.02, -0.05);
      arm.b = pose * Eigen::Vector3d(-0.48, -1.6, -0.6);
      c.occluder = arm;
    }
    const std::string name = files::replay_image_name(k);
    for (Eye eye : {Eye::kLeft, Eye::kRight}) {
      RenderConditions ce = c;
      if (eye == Eye::kRight) ce.gain *= 0.96, ce.offset = 3.0;  // the two sensors never match exactly
      cv::Mat img = renderer.render(eye, pose, ce, rng);
      if (o.colour) cv::cvtColor(img, img, cv::COLOR_GRAY2BGR);
      const fs::path p = dir / (eye == Eye::kLeft ? "left" : "right") / name;
      try {
        image::write_png(p.string(), img, 1);
      } catch (const image::ImageError& e) {
        throw SequenceError(e.what());
      }
    }
    frames.add(k, t, "left/" + name, "right/" + name, motion.motion(t).matrix());
  }
  frames.finish();
}

}  // namespace

void write_sequence(const SequenceOptions& options, const fs::path& dir) {
  check_options(options);
  try {
    files::write_directory_atomically(dir, [&](const fs::path& tmp) { render_into(options, tmp); });
  } catch (const files::FileError& e) {
    throw SequenceError(e.what());
  }
}

}  // namespace dentmark::sim::stereo
