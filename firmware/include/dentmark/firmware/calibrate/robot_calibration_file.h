#pragma once
// Files of the robot-to-stereo calibration (docs/calibration.md).
//
// Samples (input of `calibrate robot --from-file`), OpenCV FileStorage YAML:
//   target_points_tool: N×3 matrix, metres (N ≥ 3, not collinear)
//   samples: sequence of { T_base_tool: 4×4 matrix, points_camL: N×3 matrix }
// Result (robot.yaml, read by the daemon: docs/station.md): dentmark_robot_calibration
// (version), T_base_camL (4×4), rms (the fit's point RMS, m),
// holdout_rms_m, holdout_max_pose_m, handeye_translation_diff_m,
// handeye_rotation_diff_rad, poses, points_per_pose, date (UTC ISO 8601), inputs_sha256,
// tool_version; from a live calibration also the target it measured: target_pattern
// (chessboard:COLSxROWS or charuco:COLSxROWS), target_square_m, target_marker_m,
// target_dictionary, T_tool_target (4×4), which `calibrate verify` re-measures.

#include <filesystem>
#include <optional>
#include <string>

#include "dentmark/firmware/calibrate/robot_fit.h"
#include "dentmark/firmware/calibrate/tool_target.h"

namespace dentmark::calibrate {

// Throws CalibrateError naming the file and the field (samples[i].points_camL, …).
RobotSamples read_robot_samples(const std::filesystem::path& path);
// Writes a samples file `--from-file` reads (atomically). Throws CalibrateError.
void write_robot_samples(const std::filesystem::path& path, const RobotSamples& samples);

struct RobotCalibrationRun {
  RobotFit fit;
  int poses = 0;
  int points_per_pose = 0;
  std::string created_utc, inputs_sha256, tool_version;
  std::optional<ToolTarget> target;  // live mode: the target measured
};

std::string robot_calibration_yaml(const RobotCalibrationRun& run);
std::string robot_calibration_json(const RobotCalibrationRun& run);
// Atomic (common/atomic_file.h). Throws CalibrateError.
void write_robot_calibration(const std::string& path, const RobotCalibrationRun& run);

// Limits on a robot.yaml's recorded residuals (design.md §9: ≤ 1 mm point transfer).
struct RobotResidualLimits {
  double max_rms_m = 0.001;
  double max_holdout_m = 0.001;
  // Disagreement with the hand-eye cross-check: a gross-error check (a wrong pose
  // convention, a wrong mount drawing). Shah's closed form works from each sample's
  // target pose, far noisier than the points themselves: 1–3 mm on 20 synthetic poses
  // where the rigid fit is within 0.1 mm.
  double max_handeye_translation_m = 0.010;
};
// Reads T_base_camL, refusing (CalibrateError naming the file and field) a missing or
// non-4×4 matrix, non-finite values, a non-rigid transform (rotation not orthonormal
// within 1e-3 or determinant not +1, last row not 0 0 0 1) and residuals over 'limits'.
Transform load_robot_calibration(const std::filesystem::path& path, const RobotResidualLimits& limits = {});
// The target a live calibration recorded, or nullopt when the file has none (written
// from a samples file). Throws CalibrateError on a malformed target.
std::optional<ToolTarget> load_robot_target(const std::filesystem::path& path);

}  // namespace dentmark::calibrate
