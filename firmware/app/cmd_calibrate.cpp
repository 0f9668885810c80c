// `dentmark-edge calibrate stereo`: the tracking pair's calibration from image pairs
// of a chessboard or ChArUco target; `calibrate robot --from-file`: T_base_camL from
// recorded samples (docs/calibration.md). Exit 0: written; 2: bad input (nothing
// written); 3: the result is over the residual limits its loader enforces (nothing
// written).
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>

#include "commands.h"
#include "dentmark/common/log.h"
#include "dentmark/common/version.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"
#include "dentmark/firmware/calibrate/input_digest.h"
#include "dentmark/firmware/calibrate/robot_calibration_file.h"
#include "dentmark/firmware/calibrate/stereo_calibration_file.h"
#include "dentmark/firmware/calibrate/stereo_from_images.h"

namespace dentmark::edge {
namespace {

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

struct CalibrateRobotCliOptions {
  std::string from_file;
  std::string out = "robot.yaml";
  bool json = false;
};

int run_calibrate_robot(const CalibrateRobotCliOptions& o) {
  try {
    require_out_folder(o.out);
    const calibrate::RobotSamples samples = calibrate::read_robot_samples(o.from_file);
    calibrate::RobotCalibrationRun run;
    run.fit = calibrate::fit_robot(samples);
    run.poses = static_cast<int>(samples.samples.size());
    run.points_per_pose = static_cast<int>(samples.target_points_tool.size());
    run.created_utc = calibrate::utc_now_iso8601();
    run.inputs_sha256 = calibrate::inputs_sha256("robot samples\0", {o.from_file});
    run.tool_version = kVersion;
    const calibrate::RobotFit& f = run.fit;
    const calibrate::RobotResidualLimits lim;
    char bad[200] = "";
    if (f.rms_m > lim.max_rms_m)
      std::snprintf(bad, sizeof bad, "fit RMS %.3f mm > %.3f mm", f.rms_m * 1e3, lim.max_rms_m * 1e3);
    else if (f.holdout_rms_m > lim.max_holdout_m)
      std::snprintf(bad, sizeof bad, "hold-out RMS %.3f mm > %.3f mm", f.holdout_rms_m * 1e3,
                    lim.max_holdout_m * 1e3);
    else if (f.handeye_translation_diff_m > lim.max_handeye_translation_m)
      std::snprintf(bad, sizeof bad, "hand-eye cross-check differs by %.3f mm > %.3f mm",
                    f.handeye_translation_diff_m * 1e3, lim.max_handeye_translation_m * 1e3);
    if (!*bad) calibrate::write_robot_calibration(o.out, run);
    if (o.json) {
      std::cout << calibrate::robot_calibration_json(run) << std::endl;
    } else {
      std::printf("poses: %d, target points per pose: %d\n", run.poses, run.points_per_pose);
      std::printf("rigid fit RMS: %.3f mm\n", f.rms_m * 1e3);
      std::printf("hold-out point transfer (leave one pose out): RMS %.3f mm, worst pose %.3f mm\n",
                  f.holdout_rms_m * 1e3, f.holdout_max_pose_m * 1e3);
      std::printf("hand-eye cross-check (calibrateRobotWorldHandEye): %.3f mm, %.3f mrad apart\n",
                  f.handeye_translation_diff_m * 1e3, f.handeye_rotation_diff_rad * 1e3);
      if (!*bad) std::printf("written: %s\n", o.out.c_str());
    }
    if (*bad) {
      log::error(std::string("calibrate robot: ") + bad + "; " + o.out +
                 " not written: re-record the samples");
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
  CLI::App* cmd = app.add_subcommand("calibrate", "Calibrate the station (stereo pair, robot to stereo)");
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
  CLI::App* robot =
      cmd->add_subcommand("robot", "Robot-to-stereo calibration (T_base_camL) from recorded samples");
  robot
      ->add_option("--from-file", ropt->from_file,
                   "Samples: target points in the tool frame, robot poses, "
                   "triangulated points (OpenCV FileStorage YAML)")
      ->required();
  robot->add_option("--out", ropt->out, "Calibration file to write (default robot.yaml)");
  robot->add_flag("--json", ropt->json, "Print the figures as JSON");
  robot->callback([ropt] { exit_code() = run_calibrate_robot(*ropt); });
}

}  // namespace dentmark::edge
