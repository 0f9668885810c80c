// `dentmark-edge calibrate stereo`: the tracking pair's calibration from image pairs
// of a chessboard or ChArUco target; `calibrate robot`: T_base_camL, live (the robot
// carries its target through planned poses) or from recorded samples (--from-file);
// `calibrate verify`: does the stored robot calibration still hold; `calibrate scanner`:
// T_camL_sls from scans and image pairs of the scanner target
// (docs/calibration.md). Exit 0: written / holds; 1: verify: does not hold (marker
// written); 2: bad input (nothing written); 3: the result is over the residual limits
// its loader enforces (nothing written); 4: the robot or a camera failed.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "commands.h"
#include "dentmark/common/clock/clock.h"
#include "dentmark/common/log.h"
#include "dentmark/common/version.h"
#include "dentmark/firmware/board/board_config.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"
#include "dentmark/firmware/calibrate/input_digest.h"
#include "dentmark/firmware/calibrate/robot_calibration_file.h"
#include "dentmark/firmware/calibrate/robot_live.h"
#include "dentmark/firmware/calibrate/scanner_calibration.h"
#include "dentmark/firmware/calibrate/stereo_calibration_file.h"
#include "dentmark/firmware/calibrate/stereo_from_images.h"
#include "dentmark/firmware/hal/camera/camera.h"
#include "dentmark/firmware/simulation/calibration_devices.h"
#include "dentmark/firmware/station/calibration_marker.h"

namespace dentmark::edge {
namespace {

// Into 'bad': why a fit's residuals are over their limits (m); left empty when within.
void residuals_over(double rms_m, double max_rms_m, double holdout_m, double max_holdout_m, char* bad,
                    std::size_t size) {
  if (rms_m > max_rms_m)
    std::snprintf(bad, size, "fit RMS %.3f mm > %.3f mm", rms_m * 1e3, max_rms_m * 1e3);
  else if (holdout_m > max_holdout_m)
    std::snprintf(bad, size, "hold-out RMS %.3f mm > %.3f mm", holdout_m * 1e3, max_holdout_m * 1e3);
}

struct CalibrateStereoCliOptions {
  std::string images;
  std::string pattern;
  double square = 0.0;
  double marker = 0.0;
  std::string dictionary;
  std::string out = "stereo.yaml";
  std::string model = "standard";
  bool json = false;
};

void print_report(const calibrate::StereoCalibrationRun& run, const std::string& out) {
  const calibrate::StereoFit& f = run.fit;
  std::printf("view  used  left px  right px  hold-out px  rejected because\n");
  for (const calibrate::ViewFigures& v : run.views)
    std::printf("%-5s %-5s %7.3f  %8.3f  %11.3f  %s\n", v.name.c_str(), v.used ? "yes" : "no", v.rms_left_px,
                v.rms_right_px, v.holdout_rms_px, v.rejected_because.c_str());
  std::printf("views used: %d of %zu\n", f.views_used, run.views.size());
  std::printf("stereo RMS reprojection error: %.3f px (left %.3f, right %.3f)\n", f.rms_px, f.rms_left_px,
              f.rms_right_px);
  std::printf("rectified epipolar error: mean %.3f px, max %.3f px\n", f.epipolar_rectified_px,
              f.epipolar_rectified_max_px);
  std::printf("hold-out (leave one out): RMS %.3f px, worst view %.3f px\n", f.holdout_rms_px,
              f.holdout_max_view_px);
  std::printf("square: measured %.5f m, given %.5f m (%+.2f %%)\n", f.square_measured_m, f.square_given_m,
              100.0 * (f.square_measured_m / f.square_given_m - 1.0));
  std::printf("baseline: %.4f m\n", f.calibration.T_camR_camL.translation().norm());
  if (!out.empty()) std::printf("written: %s\n", out.c_str());
}

// The first residual over the tracker's limits, or empty.
std::string over_limits(const calibrate::StereoFit& f, const track::StereoResidualLimits& lim) {
  char b[160];
  if (f.rms_px > lim.max_rms_px) {
    std::snprintf(b, sizeof b, "stereo RMS %.3f px > %.3f px", f.rms_px, lim.max_rms_px);
    return b;
  }
  if (f.epipolar_rectified_px > lim.max_epipolar_px) {
    std::snprintf(b, sizeof b, "rectified epipolar error %.3f px > %.3f px", f.epipolar_rectified_px,
                  lim.max_epipolar_px);
    return b;
  }
  if (f.holdout_rms_px > lim.max_holdout_px) {
    std::snprintf(b, sizeof b, "hold-out RMS %.3f px > %.3f px", f.holdout_rms_px, lim.max_holdout_px);
    return b;
  }
  return {};
}

void require_out_folder(const std::string& out) {
  const std::filesystem::path dir = std::filesystem::absolute(out).parent_path();
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec))
    throw calibrate::CalibrateError("--out " + out + ": folder " + dir.string() + " does not exist");
}

int run_calibrate_stereo(const CalibrateStereoCliOptions& o) {
  try {
    const calibrate::TargetSpec target = calibrate::parse_target(o.pattern, o.square, o.marker, o.dictionary);
    require_out_folder(o.out);  // before minutes of work
    calibrate::StereoFitOptions options;
    options.model =
        o.model == "rational" ? calibrate::DistortionModel::kRational : calibrate::DistortionModel::kStandard;
    const auto start = std::chrono::steady_clock::now();
    const calibrate::StereoCalibrationRun run = calibrate::calibrate_stereo_images(o.images, target, options);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const std::string bad = over_limits(run.fit, track::StereoResidualLimits{});
    if (bad.empty()) calibrate::write_stereo_calibration(o.out, run);
    if (o.json)
      std::cout << calibrate::stereo_calibration_json(run) << std::endl;
    else
      print_report(run, bad.empty() ? o.out : std::string());
    log::info("calibrate stereo: " + std::to_string(run.views.size()) + " pairs in " +
              std::to_string(seconds) + " s");
    if (!bad.empty()) {
      log::error("calibrate stereo: " + bad + "; " + o.out +
                 " not written (the tracker would refuse it): retake the views (docs/calibration.md)");
      return 3;
    }
    return 0;
  } catch (const calibrate::CalibrateError& e) {
    log::error(e.what());
    return 2;
  }
}

struct TargetCliOptions {
  std::string pattern = "chessboard:7x6";
  double square = 0.03;
  double marker = 0.0;
  std::string dictionary;
  std::vector<double> in_tool;  // x y z rx ry rz
};

struct CalibrateRobotCliOptions {
  std::string from_file;
  std::string board, calibration, sim_scene, samples_out;
  int poses = 20;
  TargetCliOptions target;
  std::string out;  // default: <calibration>/robot.yaml, else robot.yaml
  bool json = false;
};

struct CalibrateVerifyCliOptions {
  std::string board, calibration, sim_scene;
  int poses = 4;
  bool json = false;
};

// Exit code of a device failure (robot link, cameras) in the live modes.
constexpr int kDeviceFailure = 4;

calibrate::ToolTarget tool_target_of(const TargetCliOptions& o) {
  calibrate::ToolTarget t;
  t.spec = calibrate::parse_target(o.pattern, o.square, o.marker, o.dictionary);
  calibrate::require_oriented_chessboard(t.spec);
  t.T_tool_target = calibrate::parse_pose6(o.in_tool, "--target-in-tool");
  return t;
}

board::BoardConfig board_of(const std::string& file) {
  try {
    return board::load_board_config(file);
  } catch (const board::BoardError& e) {
    throw calibrate::CalibrateError(e.what());
  }
}

track::StereoCalibration stereo_of(const std::filesystem::path& dir, const board::BoardConfig& board) {
  track::StereoCalibration s;
  try {
    s = track::load_stereo_calibration(dir / "stereo.yaml");
  } catch (const std::exception& e) {
    throw calibrate::CalibrateError(e.what());
  }
  if (s.size != cv::Size(board.camera.width, board.camera.height))
    throw calibrate::CalibrateError((dir / "stereo.yaml").string() + ": calibrated for " +
                                    std::to_string(s.size.width) + "x" + std::to_string(s.size.height) +
                                    ", the board's cameras give " + std::to_string(board.camera.width) + "x" +
                                    std::to_string(board.camera.height));
  return s;
}

calibrate::PosePlanOptions plan_of(const board::BoardConfig& board, int poses) {
  calibrate::PosePlanOptions p;
  p.poses = poses;
  p.workspace_min = board.limits.workspace_min;
  p.workspace_max = board.limits.workspace_max;
  return p;
}

calibrate::PoseProgress log_progress(const char* what) {
  return [what](std::size_t i, std::size_t n, const calibrate::PoseRecord& r) {
    char b[200];
    std::snprintf(b, sizeof b, "%s: pose %zu/%zu at (%.3f, %.3f, %.3f) m: ", what, i + 1, n,
                  r.T_base_tool.translation().x(), r.T_base_tool.translation().y(),
                  r.T_base_tool.translation().z());
    log::info(std::string(b) + (r.used ? "target measured" : "skipped: " + r.why));
  };
}

// Removes the folder's "calibration known bad" marker after a good result.
void clear_marker(const std::string& dir) {
  if (dir.empty()) return;
  try {
    if (station::clear_calibration_bad(dir))
      log::info(dir + "/" + station::kCalibrationBadFile + " removed: the calibration holds");
  } catch (const std::exception& e) {
    log::warn(std::string("cannot remove the calibration marker: ") + e.what());
  }
}

struct LiveRun {
  calibrate::RobotSamples samples;
  calibrate::RobotFit fit;
  calibrate::ToolTarget target;
  int planned = 0;
  double robot_seconds = 0.0, wall_seconds = 0.0;
  std::vector<calibrate::PoseRecord> poses;
};

LiveRun run_live(const CalibrateRobotCliOptions& o) {
  const board::BoardConfig board = board_of(o.board);
  const track::StereoCalibration stereo = stereo_of(o.calibration, board);
  LiveRun run;
  run.target = tool_target_of(o.target);
  clock::Clock& clock = clock::monotonic_clock();
  const auto devices = simulation::open_calibration_devices(board, o.sim_scene, clock);
  calibrate::TargetRig rig(*devices->robot, *devices->left, *devices->right, clock, stereo, run.target);
  const auto start = std::chrono::steady_clock::now();
  calibrate::LiveCalibration live = calibrate::calibrate_robot_live(
      rig, run.target, stereo, plan_of(board, o.poses), log_progress("calibrate robot"));
  run.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  devices->robot->disconnect();
  run.samples = std::move(live.acquisition.samples);
  run.fit = live.fit;
  run.planned = static_cast<int>(live.planned.size());
  run.robot_seconds = live.acquisition.robot_seconds;
  run.poses = std::move(live.acquisition.poses);
  return run;
}

// What the robot calibration's result says, for the file, from a live run.
calibrate::RobotCalibrationRun robot_run_from_live(const LiveRun& lr, const CalibrateRobotCliOptions& o) {
  calibrate::RobotCalibrationRun run;
  run.fit = lr.fit;
  run.target = lr.target;
  run.poses = static_cast<int>(lr.samples.samples.size());
  run.points_per_pose = static_cast<int>(lr.samples.target_points_tool.size());
  run.inputs_sha256 =
      o.samples_out.empty() ? std::string() : calibrate::inputs_sha256("robot samples\0", {o.samples_out});
  return run;
}

// ... and from recorded samples.
calibrate::RobotCalibrationRun robot_run_from_file(const std::string& samples_file) {
  const calibrate::RobotSamples samples = calibrate::read_robot_samples(samples_file);
  calibrate::RobotCalibrationRun run;
  run.fit = calibrate::fit_robot(samples);
  run.poses = static_cast<int>(samples.samples.size());
  run.points_per_pose = static_cast<int>(samples.target_points_tool.size());
  run.inputs_sha256 = calibrate::inputs_sha256("robot samples\0", {samples_file});
  return run;
}

// Why the fit is not good enough to write, or "" when it is.
std::string robot_fit_problem(const calibrate::RobotFit& f) {
  const calibrate::RobotResidualLimits lim;
  char bad[200] = "";
  residuals_over(f.rms_m, lim.max_rms_m, f.holdout_rms_m, lim.max_holdout_m, bad, sizeof bad);
  if (!*bad && f.handeye_translation_diff_m > lim.max_handeye_translation_m)
    std::snprintf(bad, sizeof bad, "hand-eye cross-check differs by %.3f mm > %.3f mm",
                  f.handeye_translation_diff_m * 1e3, lim.max_handeye_translation_m * 1e3);
  return bad;
}

// The result on stdout, as JSON or a table; 'written' is the file written, or "".
void print_robot_result(const calibrate::RobotCalibrationRun& run, const std::optional<LiveRun>& lr,
                        const std::string& written, bool json) {
  const calibrate::RobotFit& f = run.fit;
  if (json) {
    nlohmann::json j = nlohmann::json::parse(calibrate::robot_calibration_json(run));
    if (lr) {
      j["poses_planned"] = lr->planned;
      j["robot_seconds"] = lr->robot_seconds;
      j["wall_seconds"] = lr->wall_seconds;
      nlohmann::json skipped = nlohmann::json::array();
      for (std::size_t i = 0; i < lr->poses.size(); ++i)
        if (!lr->poses[i].used) skipped.push_back({{"pose", i + 1}, {"why", lr->poses[i].why}});
      j["poses_skipped"] = skipped;
    }
    j["written"] = written;
    std::cout << j.dump(2) << std::endl;
    return;
  }
  if (lr)
    std::printf("poses planned: %d, target measured at %d; robot time %.1f s, wall time %.1f s\n",
                lr->planned, run.poses, lr->robot_seconds, lr->wall_seconds);
  std::printf("poses: %d, target points per pose: %d\n", run.poses, run.points_per_pose);
  std::printf("rigid fit RMS: %.3f mm\n", f.rms_m * 1e3);
  std::printf("hold-out point transfer (leave one pose out): RMS %.3f mm, worst pose %.3f mm\n",
              f.holdout_rms_m * 1e3, f.holdout_max_pose_m * 1e3);
  std::printf("hand-eye cross-check (calibrateRobotWorldHandEye): %.3f mm, %.3f mrad apart\n",
              f.handeye_translation_diff_m * 1e3, f.handeye_rotation_diff_rad * 1e3);
  if (!written.empty()) std::printf("written: %s\n", written.c_str());
}

int run_calibrate_robot(const CalibrateRobotCliOptions& o) {
  try {
    const bool live = o.from_file.empty();
    if (live && (o.board.empty() || o.calibration.empty()))
      throw calibrate::CalibrateError(
          "calibrate robot: give --from-file FILE, or --board FILE and --calibration DIR");
    if (!live && !o.board.empty())
      throw calibrate::CalibrateError("calibrate robot: --from-file and --board exclude each other");
    const std::string out = !o.out.empty() ? o.out
                            : o.calibration.empty()
                                ? std::string("robot.yaml")
                                : (std::filesystem::path(o.calibration) / "robot.yaml").string();
    require_out_folder(out);
    std::optional<LiveRun> lr;
    if (live) {
      try {
        lr = run_live(o);
      } catch (const hal::RobotError& e) {
        log::error(std::string("calibrate robot: robot: ") + e.what());
        return kDeviceFailure;
      } catch (const hal::CameraError& e) {
        log::error(std::string("calibrate robot: camera: ") + e.what());
        return kDeviceFailure;
      }
      if (!o.samples_out.empty()) calibrate::write_robot_samples(o.samples_out, lr->samples);
    }
    calibrate::RobotCalibrationRun run = lr ? robot_run_from_live(*lr, o) : robot_run_from_file(o.from_file);
    run.created_utc = calibrate::utc_now_iso8601();
    run.tool_version = kVersion;
    const std::string bad = robot_fit_problem(run.fit);
    if (bad.empty()) {
      calibrate::write_robot_calibration(out, run);
      clear_marker(o.calibration);
    }
    print_robot_result(run, lr, bad.empty() ? out : std::string(), o.json);
    if (!bad.empty()) {
      log::error("calibrate robot: " + bad + "; " + out +
                 " not written: " + (live ? "run it again (docs/calibration.md)" : "re-record the samples"));
      return 3;
    }
    return 0;
  } catch (const calibrate::CalibrateError& e) {
    log::error(e.what());
    return 2;
  } catch (const std::runtime_error& e) {  // devices that cannot be opened, a bad scene
    log::error(std::string("calibrate robot: ") + e.what());
    return 2;
  }
}

int run_calibrate_verify(const CalibrateVerifyCliOptions& o) {
  try {
    const board::BoardConfig board = board_of(o.board);
    const std::filesystem::path dir(o.calibration);
    const track::StereoCalibration stereo = stereo_of(dir, board);
    const Transform T_base_camL = calibrate::load_robot_calibration(dir / "robot.yaml");
    const std::optional<calibrate::ToolTarget> target = calibrate::load_robot_target(dir / "robot.yaml");
    if (!target)
      throw calibrate::CalibrateError(
          (dir / "robot.yaml").string() +
          ": no target recorded (a file from --from-file): calibrate with the robot "
          "first (calibrate robot --board)");
    clock::Clock& clock = clock::monotonic_clock();
    calibrate::LiveVerify v;
    try {
      const auto devices = simulation::open_calibration_devices(board, o.sim_scene, clock);
      calibrate::TargetRig rig(*devices->robot, *devices->left, *devices->right, clock, stereo, *target);
      calibrate::PosePlanOptions plan = plan_of(board, o.poses);
      plan.halton_offset = 5000;  // other poses than the calibration's
      v = calibrate::verify_robot_live(rig, *target, stereo, T_base_camL, plan,
                                       board.calibration.verify_tolerance, log_progress("calibrate verify"));
      devices->robot->disconnect();
    } catch (const hal::RobotError& e) {
      log::error(std::string("calibrate verify: robot: ") + e.what());
      return kDeviceFailure;
    } catch (const hal::CameraError& e) {
      log::error(std::string("calibrate verify: camera: ") + e.what());
      return kDeviceFailure;
    }
    const calibrate::VerifyResult& r = v.result;
    if (r.holds) {
      clear_marker(o.calibration);
    } else {
      station::mark_calibration_bad(dir,
                                    "calibrate verify " + calibrate::utc_now_iso8601() + ": " + r.reason);
      log::error("calibrate verify: the stored calibration does not hold: " + r.reason + "; " +
                 (dir / station::kCalibrationBadFile).string() +
                 " written: the daemon refuses jobs until the robot is calibrated again");
    }
    if (o.json) {
      nlohmann::json j;
      j["holds"] = r.holds;
      j["reason"] = r.reason;
      j["poses_planned"] = r.poses_planned;
      j["poses_measured"] = r.poses_measured;
      j["rms_m"] = r.rms_m;
      j["max_pose_m"] = r.max_pose_m;
      j["pose_rms_m"] = r.pose_rms_m;
      j["tolerance_m"] = r.tolerance_m;
      j["robot_seconds"] = v.acquisition.robot_seconds;
      std::cout << j.dump(2) << std::endl;
    } else {
      std::printf("poses: %d planned, target measured at %d; robot time %.1f s\n", r.poses_planned,
                  r.poses_measured, v.acquisition.robot_seconds);
      std::printf(
          "point transfer with the stored T_base_camL: RMS %.3f mm, worst pose %.3f mm (tolerance %.3f mm)\n",
          r.rms_m * 1e3, r.max_pose_m * 1e3, r.tolerance_m * 1e3);
      std::printf("%s\n", r.holds ? "calibration holds" : ("calibration does NOT hold: " + r.reason).c_str());
    }
    return r.holds ? 0 : 1;
  } catch (const calibrate::CalibrateError& e) {
    log::error(e.what());
    return 2;
  } catch (const std::runtime_error& e) {
    log::error(std::string("calibrate verify: ") + e.what());
    return 2;
  }
}

struct CalibrateScannerCliOptions {
  std::string captures, target, calibration, out, scan_unit = "m";
  bool json = false;
};

int run_calibrate_scanner(const CalibrateScannerCliOptions& o) {
  try {
    const std::filesystem::path dir(o.calibration);
    const std::string out = !o.out.empty() ? o.out : (dir / "scanner.yaml").string();
    require_out_folder(out);
    track::StereoCalibration stereo;
    try {
      stereo = track::load_stereo_calibration(dir / "stereo.yaml");
    } catch (const std::exception& e) {
      throw calibrate::CalibrateError(e.what());
    }
    const calibrate::ScannerTarget target = calibrate::read_scanner_target(o.target);
    const double scale = o.scan_unit == "mm" ? 0.001 : 1.0;
    const auto start = std::chrono::steady_clock::now();
    calibrate::ScannerCalibrationRun run =
        calibrate::calibrate_scanner_captures(o.captures, target, stereo, scale);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    run.created_utc = calibrate::utc_now_iso8601();
    run.tool_version = kVersion;
    const calibrate::ScannerFit& f = run.fit;
    const calibrate::ScannerResidualLimits lim;
    char bad[200] = "";
    residuals_over(f.rms_m, lim.max_rms_m, f.holdout_rms_m, lim.max_holdout_m, bad, sizeof bad);
    if (!*bad) calibrate::write_scanner_calibration(out, run);
    if (o.json) {
      nlohmann::json j = nlohmann::json::parse(calibrate::scanner_calibration_json(run));
      j["written"] = *bad ? std::string() : out;
      j["wall_seconds"] = seconds;
      std::cout << j.dump(2) << std::endl;
    } else {
      std::printf("capture  spheres  drawing vs scan mm  board corners px\n");
      for (const calibrate::ScannerCapture& c : run.captures)
        std::printf("%-8s %7zu  %18.3f  %16.3f\n", c.name.c_str(), c.ids.size(), c.match_rms_m * 1e3,
                    c.board_rms_px);
      for (const calibrate::ScannerCapture& c : run.captures)
        for (const std::string& why : c.not_spheres)
          std::printf("capture %s: not a sphere: %s\n", c.name.c_str(), why.c_str());
      std::printf("captures: %d, common points (sphere centres): %d; %.1f s\n", f.captures, f.points,
                  seconds);
      if (f.corners_rms_px >= 0.0)
        std::printf("board corners through T_camL_sls (all captures, both cameras): RMS %.3f px\n",
                    f.corners_rms_px);
      std::printf("RMS point transfer: %.3f mm, worst point %.3f mm\n", f.rms_m * 1e3, f.max_m * 1e3);
      if (f.holdout_rms_m >= 0.0)
        std::printf("hold-out point transfer (leave one point out): RMS %.3f mm, worst point %.3f mm\n",
                    f.holdout_rms_m * 1e3, f.holdout_max_m * 1e3);
      else
        std::printf("hold-out point transfer: not computed (fewer than 5 common points)\n");
      if (!*bad) std::printf("written: %s\n", out.c_str());
    }
    if (*bad) {
      log::error(std::string("calibrate scanner: ") + bad + "; " + out +
                 " not written: check the target's drawing and retake the captures (docs/calibration.md)");
      return 3;
    }
    return 0;
  } catch (const calibrate::CalibrateError& e) {
    log::error(e.what());
    return 2;
  }
}

}  // namespace

void register_calibrate(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand(
      "calibrate", "Calibrate the station (stereo pair, robot to stereo, scanner to stereo)");
  cmd->require_subcommand(1);
  auto opt = std::make_shared<CalibrateStereoCliOptions>();
  CLI::App* stereo =
      cmd->add_subcommand("stereo", "Calibrate the tracking stereo pair from left/right image pairs");
  stereo->add_option("--images", opt->images, "Folder of left<N>.<ext> / right<N>.<ext> image pairs")
      ->required();
  stereo
      ->add_option("--pattern", opt->pattern,
                   "Target: chessboard:COLSxROWS (inner corners) or charuco:COLSxROWS (squares)")
      ->required();
  stereo->add_option("--square", opt->square, "Square side, metres")->required();
  stereo->add_option("--marker", opt->marker, "ChArUco marker side, metres");
  stereo->add_option("--dictionary", opt->dictionary, "ChArUco marker dictionary (e.g. DICT_5X5_100)");
  stereo
      ->add_option("--model", opt->model,
                   "Distortion model: standard (k1 k2 p1 p2 k3) or rational (8 coefficients)")
      ->check(CLI::IsMember({"standard", "rational"}));
  stereo->add_option("--out", opt->out, "Calibration file to write (default stereo.yaml)");
  stereo->add_flag("--json", opt->json, "Print the figures as JSON");
  stereo->callback([opt] { exit_code() = run_calibrate_stereo(*opt); });

  auto ropt = std::make_shared<CalibrateRobotCliOptions>();
  CLI::App* robot = cmd->add_subcommand(
      "robot",
      "Robot-to-stereo calibration (T_base_camL): live, driving the robot, or from recorded samples");
  robot->add_option("--from-file", ropt->from_file,
                    "Recorded samples: target points in the tool frame, robot poses, "
                    "triangulated points (OpenCV FileStorage YAML)");
  robot->add_option("--board", ropt->board, "Live: board file (robot link, cameras, workspace limits)");
  robot->add_option("--calibration", ropt->calibration,
                    "Calibration folder (stereo.yaml is read; robot.yaml is written there by default)");
  robot->add_option("--poses", ropt->poses, "Live: poses to plan and visit (default 20)")
      ->check(CLI::Range(6, 200));
  robot->add_option("--target", ropt->target.pattern,
                    "Live: the tool's target, chessboard:COLSxROWS (COLS+ROWS odd) or charuco:COLSxROWS "
                    "(default chessboard:7x6)");
  robot->add_option("--square", ropt->target.square, "Live: the target's square side, metres (default 0.03)");
  robot->add_option("--marker", ropt->target.marker, "Live: ChArUco marker side, metres");
  robot->add_option("--dictionary", ropt->target.dictionary, "Live: ChArUco dictionary (e.g. DICT_5X5_100)");
  robot
      ->add_option("--target-in-tool", ropt->target.in_tool,
                   "Live: the target's pose on the tool, x y z (m) rx ry rz (rad), from the mount's drawing")
      ->expected(6);
  robot->add_option("--samples-out", ropt->samples_out,
                    "Live: also write the samples taken (a --from-file file)");
  robot->add_option("--sim-scene", ropt->sim_scene, "Twin only: the simulated cameras' scene (ground truth)");
  robot->add_option("--out", ropt->out,
                    "Calibration file to write (default <calibration>/robot.yaml or robot.yaml)");
  robot->add_flag("--json", ropt->json, "Print the figures as JSON");
  robot->callback([ropt] { exit_code() = run_calibrate_robot(*ropt); });

  auto vopt = std::make_shared<CalibrateVerifyCliOptions>();
  CLI::App* verify = cmd->add_subcommand(
      "verify", "Check that the stored robot calibration still holds (exit 0 holds, 1 does not)");
  verify->add_option("--board", vopt->board, "Board file (robot, cameras, calibration.verify_tolerance)")
      ->required();
  verify->add_option("--calibration", vopt->calibration, "Calibration folder (stereo.yaml, robot.yaml)")
      ->required();
  verify->add_option("--poses", vopt->poses, "Poses to re-measure (default 4)")->check(CLI::Range(1, 50));
  verify->add_option("--sim-scene", vopt->sim_scene,
                     "Twin only: the simulated cameras' scene (ground truth)");
  verify->add_flag("--json", vopt->json, "Print the figures as JSON");
  verify->callback([vopt] { exit_code() = run_calibrate_verify(*vopt); });
  auto sopt = std::make_shared<CalibrateScannerCliOptions>();
  CLI::App* scanner = cmd->add_subcommand(
      "scanner",
      "Scanner-to-stereo calibration (T_camL_sls) from scans and image pairs of the scanner target");
  scanner
      ->add_option("--captures", sopt->captures,
                   "Folder of captures: scan<N>.<ply|xyz|...> with left<N>.<ext> / right<N>.<ext>")
      ->required();
  scanner
      ->add_option("--target", sopt->target,
                   "The scanner target's file (chessboard, sphere radius and layout)")
      ->required();
  scanner
      ->add_option("--calibration", sopt->calibration,
                   "Calibration folder (stereo.yaml is read; scanner.yaml is written there by default)")
      ->required();
  scanner->add_option("--scan-unit", sopt->scan_unit, "Length unit of the scan files: m (default) or mm")
      ->check(CLI::IsMember({"m", "mm"}));
  scanner->add_option("--out", sopt->out, "Calibration file to write (default <calibration>/scanner.yaml)");
  scanner->add_flag("--json", sopt->json, "Print the figures as JSON");
  scanner->callback([sopt] { exit_code() = run_calibrate_scanner(*sopt); });
}

}  // namespace dentmark::edge
