#include "dentmark/sim/stereo_raytrace/ray_sequence.h"

#include <Eigen/Core>
#include <cmath>
#include <iomanip>
#include <numbers>
#include <opencv2/core/eigen.hpp>
#include <random>
#include <sstream>

#include "dentmark/common/atomic_file.h"
#include "dentmark/common/image/png_io.h"
#include "dentmark/common/replay_files.h"
#include "dentmark/sim/stereo_raytrace/conveyor.h"
#include "dentmark/sim/stereo_raytrace/ray_tracer.h"

namespace dentmark::sim::raytrace {
namespace fs = std::filesystem;
namespace {

void check(const RaySequenceOptions& o) {
  auto bad = [](const std::string& what) { throw RaySequenceError("ray-traced stereo: " + what); };
  if (o.width < 64 || o.height < 64 || o.width > 8192 || o.height > 8192)
    bad("image size must be 64..8192 px");
  if (!(o.focal_px > 10.0) || !(o.pixel_pitch > 0.0)) bad("focal length and pixel pitch must be > 0");
  if (!(o.baseline > 0.0) || !(o.distance > 0.5)) bad("baseline must be > 0 m and distance > 0.5 m");
  if (!(o.seconds >= 0.0) || !(o.fps > 0.0) || o.seconds * o.fps > 100000) bad("need seconds >= 0, fps > 0");
  if (!(o.exposure >= 0.0) || o.exposure * o.fps >= 1.0) bad("exposure must be in [0, 1/fps)");
  if (o.exposure_steps < 1 || o.supersample < 1 || o.supersample % 37 == 0 || o.supersample > 32)
    bad("exposure_steps >= 1 and supersample in 1..32");
  if (!(o.f_number > 0.5) || !(o.focus > 0.1)) bad("f-number must be > 0.5 and focus > 0.1 m");
  if (!(o.lighting_drift >= 0.0 && o.lighting_drift < 0.9)) bad("lighting drift must be in [0, 0.9)");
}

struct Rig {
  BrownConrady left, right;
  Eigen::Isometry3d T_camL_camR = Eigen::Isometry3d::Identity();
};

Rig make_rig(const RaySequenceOptions& o) {
  Rig rig;
  const double f = o.focal_px, w = o.width, h = o.height;
  rig.left = {
      f, f * 1.0008, 0.5 * w + 5.2 * w / 1280, 0.5 * h - 3.1 * w / 1280, {-0.085, 0.11, 3e-4, -2e-4, 0}};
  rig.right = {f * 0.9985,
               f * 0.9991,
               0.5 * w - 2.7 * w / 1280,
               0.5 * h + 4.4 * w / 1280,
               {-0.078, 0.095, -2.5e-4, 1.5e-4, -0.01}};
  if (!o.distortion) rig.left.d = rig.right.d = {0, 0, 0, 0, 0};
  // camR a baseline to the right, a little off the line, turned to look at the door.
  const double toe = std::atan(0.5 * o.baseline / o.distance);
  rig.T_camL_camR.linear() = (Eigen::AngleAxisd(-toe, Eigen::Vector3d::UnitY()) *
                              Eigen::AngleAxisd(0.002, Eigen::Vector3d::UnitX()) *
                              Eigen::AngleAxisd(-0.0015, Eigen::Vector3d::UnitZ()))
                                 .toRotationMatrix();
  rig.T_camL_camR.translation() = Eigen::Vector3d(o.baseline, 0.002, 0.001);
  return rig;
}

cv::Mat camera_matrix(const BrownConrady& c) {
  return (cv::Mat_<double>(3, 3) << c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
}
cv::Mat distortion(const BrownConrady& c) {
  return (cv::Mat_<double>(1, 5) << c.d[0], c.d[1], c.d[2], c.d[3], c.d[4]);
}

void write_calibration(const Rig& rig, cv::Size size, const fs::path& path) {
  cv::FileStorage fs(path.string(), cv::FileStorage::WRITE);
  if (!fs.isOpened()) throw RaySequenceError(path.string() + ": cannot open for writing");
  const Eigen::Isometry3d T_camR_camL = rig.T_camL_camR.inverse();
  cv::Mat r, t;
  const Eigen::Matrix3d rr = T_camR_camL.linear();
  const Eigen::Vector3d tt = T_camR_camL.translation();
  cv::eigen2cv(rr, r);
  cv::eigen2cv(tt, t);
  fs << "image_width" << size.width << "image_height" << size.height << "K1" << camera_matrix(rig.left)
     << "D1" << distortion(rig.left) << "K2" << camera_matrix(rig.right) << "D2" << distortion(rig.right)
     << "R" << r << "T" << t;
}

Eigen::Vector2d project(const BrownConrady& lens, const Eigen::Isometry3d& T_cam_camL,
                        const Eigen::Vector3d& p) {
  const Eigen::Vector3d q = T_cam_camL * p;
  return lens.project_normalized(q.head<2>() / q.z());
}

void render_into(const RaySequenceOptions& o, const fs::path& dir) {
  const cv::Size size(o.width, o.height);
  const Rig rig = make_rig(o);
  const Door door = make_door();
  const RayTracer left(rig.left, Eigen::Isometry3d::Identity(), size, o.supersample);
  const RayTracer right(rig.right, rig.T_camL_camR, size, o.supersample);

  Conveyor line;
  line.speed = o.speed;
  line.stop_at = o.stop_at;
  line.stop_for = o.stop_for;
  line.turn_rate = o.turn_rate;
  line.direction = Eigen::Vector3d(1.0, 0.02, 0.06).normalized();
  Eigen::Isometry3d pose0 = Eigen::Isometry3d::Identity();
  pose0.linear() =
      (Eigen::AngleAxisd(0.15, Eigen::Vector3d::UnitY()) * Eigen::AngleAxisd(0.04, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  pose0.translation() =
      Eigen::Vector3d(0.5 * o.baseline, 0.22, o.distance) - 0.5 * line.travel(o.seconds) * line.direction;
  line.T_camL_panel0 = pose0;

  write_calibration(rig, size, dir / "stereo.yaml");
  fs::create_directories(dir / "left");
  fs::create_directories(dir / "right");
  std::mt19937_64 rng(o.seed);
  {
    std::uniform_real_distribution<double> jitter(-o.seed_error, o.seed_error);
    const Eigen::Isometry3d T_camR_camL = rig.T_camL_camR.inverse();
    std::vector<cv::Point2f> seeds;
    for (const auto& f : door.features) {
      const Eigen::Vector2d p = project(rig.right, T_camR_camL, pose0 * Eigen::Vector3d(f.x(), f.y(), 0.0));
      const auto x = static_cast<float>(p.x() + jitter(rng));
      const auto y = static_cast<float>(p.y() + jitter(rng));
      seeds.emplace_back(x, y);
    }
    files::write_replay_seeds(dir / "seeds.yaml", seeds);
  }
  files::write_replay_points(dir / "eval_points.csv", pose0, door.eval_points);
  files::write_replay_points(dir / "features.csv", pose0, door.features);

  files::ReplayFrameWriter frames(dir);
  const int n = static_cast<int>(std::floor(o.seconds * o.fps + 1e-9)) + 1;
  const Eigen::Isometry3d M0inv = line.T_camL_panel(0.0).inverse();
  for (int k = 0; k < n; ++k) {
    const double t = k / o.fps;
    std::vector<Eigen::Isometry3d> poses;
    for (int i = 0; i < o.exposure_steps; ++i)
      poses.push_back(line.T_camL_panel(t - 0.5 * o.exposure + o.exposure * (i + 0.5) / o.exposure_steps));
    std::optional<Arm> arm;
    if (o.occlude && t >= 0.3 * o.seconds && t <= 0.6 * o.seconds)
      arm = Arm{Eigen::Vector3d(-0.50, 0.0, -0.08), Eigen::Vector3d(-0.78, -1.5, -0.55)};
    Lighting light;
    light.level = 1.0 + o.lighting_drift * std::sin(2.0 * std::numbers::pi * t / 13.0 + 0.4);
    const double depth = line.T_camL_panel(t).translation().z();
    const std::string name = files::replay_image_name(k);
    for (int eye = 0; eye < 2; ++eye) {
      const RayTracer& tracer = eye == 0 ? left : right;
      SensorOptions s = o.sensor;
      if (eye == 1) s.electrons_at_white *= 0.94, s.black_level += 3;  // two sensors never match
      const double pitch = o.pixel_pitch;
      s.defocus_radius = circle_of_confusion_px(depth, o.focus, o.f_number, o.focal_px * pitch, pitch);
      const cv::Mat3b img = expose(tracer.render(door, arm, poses, light), tracer.corner_rays(), s, rng);
      const fs::path p = dir / (eye == 0 ? "left" : "right") / name;
      try {
        image::write_png(p.string(), img, 1);
      } catch (const image::ImageError& e) {
        throw RaySequenceError(e.what());
      }
    }
    const Eigen::Isometry3d m = line.T_camL_panel(t) * M0inv;
    frames.add(k, t, "left/" + name, "right/" + name, m.matrix());
  }
  frames.finish();
}

}  // namespace

std::string describe(const RaySequenceOptions& o) {
  std::ostringstream s;
  s << std::setprecision(10) << "v2 " << o.width << "x" << o.height << " f" << o.focal_px << " pitch"
    << o.pixel_pitch << " b" << o.baseline << " d" << o.distance << " s" << o.seconds << " fps" << o.fps
    << " v" << o.speed << " e" << o.exposure << "/" << o.exposure_steps << " ss" << o.supersample << " dist"
    << o.distortion << " N" << o.f_number << " focus" << o.focus << " drift" << o.lighting_drift << " occ"
    << o.occlude << " stop" << o.stop_at << "/" << o.stop_for << " seederr" << o.seed_error << " e-"
    << o.sensor.electrons_at_white << "/" << o.sensor.full_well << " read" << o.sensor.read_noise << " black"
    << o.sensor.black_level << " gamma" << o.sensor.gamma << " bayer" << o.sensor.bayer << " seed" << o.seed;
  if (o.turn_rate != 0.0) s << " turn" << o.turn_rate;
  return s.str();
}

void write_ray_sequence(const RaySequenceOptions& options, const fs::path& dir) {
  check(options);
  try {
    files::write_directory_atomically(dir, [&](const fs::path& tmp) { render_into(options, tmp); });
  } catch (const files::FileError& e) {
    throw RaySequenceError(e.what());
  }
}

}  // namespace dentmark::sim::raytrace
