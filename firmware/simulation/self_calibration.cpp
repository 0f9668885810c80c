#include "dentmark/firmware/simulation/self_calibration.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <functional>
#include <random>
#include <sstream>
#include <stdexcept>

#include "dentmark/common/clock/clock.h"
#include "dentmark/common/image/png_io.h"
#include "dentmark/common/ingest/mesh_writer.h"
#include "dentmark/common/log.h"
#include "dentmark/common/utc_time.h"
#include "dentmark/common/version.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"
#include "dentmark/firmware/calibrate/robot_calibration_file.h"
#include "dentmark/firmware/calibrate/robot_live.h"
#include "dentmark/firmware/calibrate/scanner_calibration.h"
#include "dentmark/firmware/calibrate/stereo_calibration_file.h"
#include "dentmark/firmware/simulation/calibration_devices.h"
#include "dentmark/firmware/station/station_calibration.h"
#include "dentmark/sim/calibration/calibration_scene.h"
#include "dentmark/sim/calibration/sphere_target_scan.h"

namespace dentmark::simulation {
namespace fs = std::filesystem;
namespace {

// A stable text of the numbers that decide a calibration's result, hashed into a key.
std::string key_of(const std::string& text) {
  // FNV-1a, 64 bit: a cache key, not a security measure.
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : text) h = (h ^ c) * 1099511628211ull;
  char b[17];
  std::snprintf(b, sizeof b, "%016llx", static_cast<unsigned long long>(h));
  return b;
}

void put(std::ostringstream& o, const Transform& t) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 4; ++j) o << ' ' << t.matrix()(i, j);
}

void put(std::ostringstream& o, const cv::Mat& m) {
  cv::Mat d;
  m.convertTo(d, CV_64F);
  for (int i = 0; i < static_cast<int>(d.total()); ++i) o << ' ' << d.at<double>(i);
}

std::string station_text(const Workcell& cell, const sim::robot::RobotSimConfig& robot) {
  std::ostringstream o;
  o.precision(12);
  o << "v2 " << kVersion << ' ' << cell.rig.size.width << 'x' << cell.rig.size.height;
  put(o, cv::Mat(cell.rig.left.K));
  put(o, cell.rig.left.D);
  put(o, cv::Mat(cell.rig.right.K));
  put(o, cell.rig.right.D);
  put(o, cell.rig.T_camR_camL);
  put(o, cell.T_base_camL_true);
  put(o, robot.accuracy_error);
  o << ' ' << robot.repeatability << ' ' << robot.seed;
  return o.str();
}

double angle(const Transform& a, const Transform& b) {
  return Eigen::AngleAxisd((a.inverse() * b).linear()).angle();
}

// A fresh folder, removed with what is in it.
struct Scratch {
  explicit Scratch(const fs::path& parent) {
    std::random_device rd;
    path = parent / ("tmp-" + std::to_string(rd()));
    fs::create_directories(path);
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  fs::path path;
};

// Step 1: 16 rendered pairs of a 9×6, 80 mm board, then `calibrate stereo`.
void calibrate_stereo_step(const Workcell& cell, const fs::path& out, const fs::path& work) {
  const sim::calibration::ChessboardTarget board{9, 6, 0.08};
  const sim::calibration::ChessboardRenderer renderer(cell.rig, board);
  const Eigen::Vector3d centre_board(0.5 * (board.cols - 1) * board.square,
                                     0.5 * (board.rows - 1) * board.square, 0.0);
  // Where both cameras look: the door's track at 2.8 m.
  const Eigen::Vector3d middle = cell.motion.T_camL_panel0.translation() + Eigen::Vector3d(0.2, 0.0, 0.0);
  std::mt19937_64 rng(4242);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  cv::RNG noise(99);
  const sim::calibration::TargetImaging imaging;
  for (int k = 1; k <= 16; ++k) {
    const Eigen::Matrix3d r = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix() *
                              make_transform_rotvec(Eigen::Vector3d(0.5 * u(rng), 0.5 * u(rng), 0.4 * u(rng)),
                                                    Eigen::Vector3d::Zero())
                                  .linear();
    const Eigen::Vector3d c = middle + Eigen::Vector3d(0.45 * u(rng), 0.3 * u(rng), 0.4 * u(rng));
    const Transform T = make_transform(r, c - r * centre_board);
    char name[32];
    std::snprintf(name, sizeof name, "%02d.png", k);
    image::write_png((work / (std::string("left") + name)).string(),
                     renderer.render(sim::stereo::Eye::kLeft, T, imaging, noise));
    image::write_png((work / (std::string("right") + name)).string(),
                     renderer.render(sim::stereo::Eye::kRight, T, imaging, noise));
  }
  calibrate::StereoCalibrationRun run = calibrate::calibrate_stereo_images(
      work, calibrate::parse_target("chessboard:9x6", board.square, 0.0, ""));
  run.created_utc = utc_now_iso8601();
  run.tool_version = kVersion;
  calibrate::write_stereo_calibration(out.string(), run);
}

// Step 2: `calibrate robot` live against a robot simulator of the scenario's robot.
void calibrate_robot_step(const Workcell& cell, board::BoardConfig board,
                          const sim::robot::RobotSimConfig& robot_config, const fs::path& stereo_yaml,
                          const fs::path& out) {
  clock::Clock& clock = clock::monotonic_clock();
  sim::robot::RobotSimConfig rc = robot_config;
  rc.heartbeat_timeout = 2.0;
  auto robot_sim = sim::robot::RobotSimulator::serve_tcp(rc, clock);
  board.modbus.host = "127.0.0.1";
  board.modbus.port = robot_sim->port();
  sim::calibration::CalibrationScene scene = sim::calibration::twin_calibration_scene();
  scene.rig = cell.rig;
  scene.T_base_camL = cell.T_base_camL_true;
  const track::StereoCalibration stereo = track::load_stereo_calibration(stereo_yaml);
  calibrate::ToolTarget target;
  target.spec = calibrate::parse_target(
      "chessboard:" + std::to_string(scene.target.cols) + "x" + std::to_string(scene.target.rows),
      scene.target.square, 0.0, "");
  target.T_tool_target = scene.T_tool_target;  // the mount's drawing
  sim::robot::RobotSimulator* truth = robot_sim.get();
  const auto devices = open_calibration_devices(board, scene, clock, [truth] { return truth->true_pose(); });
  calibrate::TargetRig rig(*devices->robot, *devices->left, *devices->right, clock, stereo, target);
  rig.connect();
  // The operator's start pose: the target facing the cameras in the middle of the volume.
  rig.move_to(make_transform_rotvec(Eigen::Vector3d(M_PI, 0, 0), Eigen::Vector3d(0.0, 0.0, 0.5)));
  calibrate::PosePlanOptions plan;
  plan.poses = 20;
  plan.workspace_min = board.limits.workspace_min;
  plan.workspace_max = board.limits.workspace_max;
  const calibrate::LiveCalibration live = calibrate::calibrate_robot_live(rig, target, stereo, plan);
  devices->robot->disconnect();
  robot_sim->stop();
  calibrate::RobotCalibrationRun run;
  run.fit = live.fit;
  run.target = target;
  run.poses = static_cast<int>(live.acquisition.samples.samples.size());
  run.points_per_pose = static_cast<int>(live.acquisition.samples.target_points_tool.size());
  run.created_utc = utc_now_iso8601();
  run.tool_version = kVersion;
  calibrate::write_robot_calibration(out.string(), run);
}

// Step 3: `calibrate scanner` on rendered captures at the door's scan position.
void calibrate_scanner_step(const Workcell& cell, const fs::path& stereo_yaml, const fs::path& out,
                            const fs::path& work) {
  const Eigen::Vector3d centre = cell.motion.T_camL_panel0.translation();
  render_scanner_captures(cell.rig, cell.T_camL_sls_true, centre, 3, 11, work, work / "target.yaml");
  calibrate::ScannerCalibrationRun run =
      calibrate::calibrate_scanner_captures(work, calibrate::read_scanner_target(work / "target.yaml"),
                                            track::load_stereo_calibration(stereo_yaml), 1.0);
  run.created_utc = utc_now_iso8601();
  run.tool_version = kVersion;
  calibrate::write_scanner_calibration(out, run);
}

template <typename F>
void step(const char* name, F&& f) {
  try {
    f();
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string("twin self-calibration, ") + name + ": " + e.what());
  }
}

}  // namespace

void render_scanner_captures(const sim::stereo::StereoRig& rig, const Transform& T_camL_sls,
                             const Eigen::Vector3d& centre, int captures, std::uint64_t seed,
                             const fs::path& dir, const fs::path& target_yaml) {
  const sim::calibration::SphereTarget target = sim::calibration::twin_sphere_target();
  calibrate::ScannerTarget drawing;
  drawing.board = calibrate::parse_target(
      "chessboard:" + std::to_string(target.board.cols) + "x" + std::to_string(target.board.rows),
      target.board.square, 0.0, "");
  drawing.sphere_radius_m = target.sphere_radius;
  drawing.spheres_board = target.spheres_board;
  calibrate::write_scanner_target(target_yaml, drawing);
  const sim::calibration::ChessboardRenderer renderer(rig, target.board);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  cv::RNG cv_rng(seed);
  const Eigen::Vector3d centre_board(0.5 * (target.plate_min.x() + target.plate_max.x()),
                                     0.5 * (target.plate_min.y() + target.plate_max.y()), 0.0);
  for (int k = 1; k <= captures; ++k) {
    // Printed face towards the cameras (board z along −camL z), tilted, moved about 'centre'.
    const Eigen::Matrix3d r =
        Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix() *
        make_transform_rotvec(Eigen::Vector3d(0.25 * u(rng), 0.25 * u(rng), 0.1 * u(rng)),
                              Eigen::Vector3d::Zero())
            .linear();
    const Eigen::Vector3d c = centre + Eigen::Vector3d(0.1 * u(rng), 0.08 * u(rng), 0.1 * u(rng));
    const Transform T_camL_board = make_transform(r, c - r * centre_board);
    const std::string n = std::to_string(k);
    const sim::calibration::TargetImaging imaging;
    image::write_png((dir / ("left" + n + ".png")).string(),
                     renderer.render(sim::stereo::Eye::kLeft, T_camL_board, imaging, cv_rng));
    image::write_png((dir / ("right" + n + ".png")).string(),
                     renderer.render(sim::stereo::Eye::kRight, T_camL_board, imaging, cv_rng));
    sim::calibration::SlsImaging sls;
    sls.spacing = 0.0015;
    sls.outlier_fraction = 0.002;
    sls.seed = seed * 100 + static_cast<std::uint64_t>(k);
    ingest::Mesh scan;
    scan.vertices = sim::calibration::scan_sphere_target(target, T_camL_sls.inverse() * T_camL_board, sls);
    ingest::write_ply((dir / ("scan" + n + ".ply")).string(), scan);
  }
}

namespace {

// The cache folder held for one twin at a time (flock(2)): scenarios run side by side,
// and the first to need a calibration makes it while the others wait, then read it.
class CacheLock {
 public:
  explicit CacheLock(const fs::path& dir) {
    const fs::path path = dir / ".lock";
    fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0 || ::flock(fd_, LOCK_EX) != 0)
      throw std::runtime_error(path.string() +
                               ": cannot lock the calibration cache: " + std::strerror(errno));
  }
  ~CacheLock() { ::close(fd_); }  // closing lets the lock go
  CacheLock(const CacheLock&) = delete;
  CacheLock& operator=(const CacheLock&) = delete;

 private:
  int fd_ = -1;
};

}  // namespace

SelfCalibrationResult self_calibrate(const Workcell& cell, const board::BoardConfig& board,
                                     const sim::robot::RobotSimConfig& robot, const fs::path& cache_dir) {
  const std::string station_key = key_of(station_text(cell, robot));
  std::ostringstream s;
  s.precision(12);
  s << station_key;
  put(s, cell.T_camL_sls_true);
  const std::string scanner_key = key_of(s.str());
  const fs::path dir = cache_dir / station_key;
  fs::create_directories(dir);
  const CacheLock lock(dir);
  SelfCalibrationResult r;
  r.stereo_yaml = dir / "stereo.yaml";
  r.robot_yaml = dir / "robot.yaml";
  r.scanner_yaml = dir / ("scanner-" + scanner_key + ".yaml");
  r.from_cache = fs::exists(r.stereo_yaml) && fs::exists(r.robot_yaml) && fs::exists(r.scanner_yaml);
  if (!fs::exists(r.stereo_yaml) || !fs::exists(r.robot_yaml)) {
    log::info("twin: commissioning the station by calibrating it (stereo, robot; cached in " + dir.string() +
              ")");
    step("stereo", [&] {
      const Scratch work(dir);
      calibrate_stereo_step(cell, r.stereo_yaml, work.path);
    });
    step("robot", [&] { calibrate_robot_step(cell, board, robot, r.stereo_yaml, r.robot_yaml); });
  }
  if (!fs::exists(r.scanner_yaml)) {
    log::info("twin: calibrating the scanner for this door pose (cached in " + r.scanner_yaml.string() + ")");
    step("scanner", [&] {
      const Scratch work(dir);
      calibrate_scanner_step(cell, r.stereo_yaml, r.scanner_yaml, work.path);
    });
  }
  const Transform T_base_camL = station::load_transform(r.robot_yaml, "T_base_camL");
  const Transform T_camL_sls = station::load_transform(r.scanner_yaml, "T_camL_sls");
  r.robot_translation_error = (T_base_camL.translation() - cell.T_base_camL_true.translation()).norm();
  r.robot_rotation_error = angle(T_base_camL, cell.T_base_camL_true);
  r.scanner_translation_error = (T_camL_sls.translation() - cell.T_camL_sls_true.translation()).norm();
  r.scanner_rotation_error = angle(T_camL_sls, cell.T_camL_sls_true);
  cv::FileStorage st(r.stereo_yaml.string(), cv::FileStorage::READ);
  r.stereo_rms_px = static_cast<double>(st["rms_px"]);
  cv::FileStorage ro(r.robot_yaml.string(), cv::FileStorage::READ);
  r.robot_holdout_rms_m = static_cast<double>(ro["holdout_rms_m"]);
  cv::FileStorage sc(r.scanner_yaml.string(), cv::FileStorage::READ);
  r.scanner_holdout_rms_m = static_cast<double>(sc["holdout_rms_m"]);
  return r;
}

}  // namespace dentmark::simulation
