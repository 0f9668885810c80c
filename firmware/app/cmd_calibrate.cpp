// `dentmark-edge calibrate stereo`: the tracking pair's calibration from image pairs
// of a chessboard or ChArUco target (docs/calibration.md). Exit 0: written; 2: bad
// input (nothing written); 3: the result is over the residual limits the tracker
// enforces (nothing written).
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>

#include "commands.h"
#include "dentmark/common/log.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"
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
  std::printf("hold-out (leave one out): RMS %.3f px, worst view %.3f px\n", f.holdout_rms_px, f.holdout_max_view_px);
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

int run_calibrate_stereo(const CalibrateStereoCliOptions& o) {
  try {
    const calibrate::TargetSpec target = calibrate::parse_target(o.pattern, o.square, o.marker, o.dictionary);
    // Refuse an unwritable --out before minutes of work.
    const std::filesystem::path out_dir = std::filesystem::absolute(o.out).parent_path();
    std::error_code ec;
    if (!std::filesystem::is_directory(out_dir, ec))
      throw calibrate::CalibrateError("--out " + o.out + ": folder " + out_dir.string() + " does not exist");
    calibrate::StereoFitOptions options;
    options.model = o.model == "rational" ? calibrate::DistortionModel::kRational : calibrate::DistortionModel::kStandard;
    const auto start = std::chrono::steady_clock::now();
    const calibrate::StereoCalibrationRun run = calibrate::calibrate_stereo_images(o.images, target, options);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const std::string bad = over_limits(run.fit, track::StereoResidualLimits{});
    if (bad.empty()) calibrate::write_stereo_calibration(o.out, run);
    if (o.json)
      std::cout << calibrate::stereo_calibration_json(run) << std::endl;
    else
      print_report(run, bad.empty() ? o.out : std::string());
    log::info("calibrate stereo: " + std::to_string(run.views.size()) + " pairs in " + std::to_string(seconds) + " s");
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

}  // namespace

void register_calibrate(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand("calibrate", "Calibrate the station (stereo pair)");
  cmd->require_subcommand(1);
  auto opt = std::make_shared<CalibrateStereoCliOptions>();
  CLI::App* stereo = cmd->add_subcommand("stereo", "Calibrate the tracking stereo pair from left/right image pairs");
  stereo->add_option("--images", opt->images, "Folder of left<N>.<ext> / right<N>.<ext> image pairs")->required();
  stereo->add_option("--pattern", opt->pattern, "Target: chessboard:COLSxROWS (inner corners) or charuco:COLSxROWS (squares)")
      ->required();
  stereo->add_option("--square", opt->square, "Square side, metres")->required();
  stereo->add_option("--marker", opt->marker, "ChArUco marker side, metres");
  stereo->add_option("--dictionary", opt->dictionary, "ChArUco marker dictionary (e.g. DICT_5X5_100)");
  stereo->add_option("--model", opt->model, "Distortion model: standard (k1 k2 p1 p2 k3) or rational (8 coefficients)")
      ->check(CLI::IsMember({"standard", "rational"}));
  stereo->add_option("--out", opt->out, "Calibration file to write (default stereo.yaml)");
  stereo->add_flag("--json", opt->json, "Print the figures as JSON");
  stereo->callback([opt] { exit_code() = run_calibrate_stereo(*opt); });
}

}  // namespace dentmark::edge
