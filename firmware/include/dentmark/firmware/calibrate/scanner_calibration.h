#pragma once
// `calibrate scanner`: T_camL_sls from a folder of captures of the scanner target
// (scanner_target.h). Capture N is the scan scan<N>.<ext> (ext ply, xyz, txt, pts, asc,
// csv, obj or stl: the scan files the host reads, common/ingest/read_scan_file.h) and
// the image pair left<N>.<ext> / right<N>.<ext> (image_pairs.h), taken with the
// target at rest. Each capture gives the matched spheres' centres in sls (scan_spheres.h)
// and in camL (the board's pose from its corners found in both images, target_measurement.h,
// refined on their reprojection error, board_pose.h, times the drawing); scanner_fit.h
// fits T_camL_sls over all.

#include <filesystem>
#include <string>
#include <vector>

#include "dentmark/firmware/calibrate/scanner_fit.h"
#include "dentmark/firmware/calibrate/scanner_target.h"
#include "dentmark/firmware/track/stereo_calibration.h"

namespace dentmark::calibrate {

struct ScannerCaptureFiles {
  std::string name;  // N as written in the left image's name
  std::filesystem::path scan, left, right;
};

// Captures sorted by N. Throws CalibrateError naming the folder or the file without its
// partner (a pair without a scan, a scan without a pair, two scans with one number).
std::vector<ScannerCaptureFiles> find_scanner_captures(const std::filesystem::path& dir);

// One capture's common points. scan_scale_to_m: the scan file's unit (mm files: 0.001).
// Throws CalibrateError naming the file: unreadable scan, spheres not found or not
// matched, the board not found whole in both images.
ScannerCapture measure_scanner_capture(const ScannerTarget& target, const track::StereoCalibration& stereo,
                                       const ScannerCaptureFiles& files, double scan_scale_to_m);

struct ScannerCalibrationRun {
  ScannerFit fit;
  std::vector<ScannerCapture> captures;
  ScannerTarget target;
  std::string created_utc, inputs_sha256, tool_version;
};

ScannerCalibrationRun calibrate_scanner_captures(const std::filesystem::path& dir,
                                                 const ScannerTarget& target,
                                                 const track::StereoCalibration& stereo,
                                                 double scan_scale_to_m);

// scanner.yaml (OpenCV FileStorage YAML): what the daemon reads (T_camL_sls, rms in
// metres, date, tool_version: station_calibration.h) and dentmark_scanner_calibration
// (format version), max_m, holdout_rms_m, holdout_max_m, captures, points, capture
// (per capture: name, sphere_ids, match_rms_m, board_rms_px), target (pattern, square,
// sphere radius, spheres_board), inputs_sha256. A figure not computed is −1.
std::string scanner_calibration_yaml(const ScannerCalibrationRun& run);
std::string scanner_calibration_json(const ScannerCalibrationRun& run);
void write_scanner_calibration(const std::filesystem::path& path, const ScannerCalibrationRun& run);

struct ScannerResidualLimits {
  double max_rms_m = 0.001;  // design.md §9: 1 mm point transfer
  double max_holdout_m = 0.001;
};
// Reads T_camL_sls, refusing (CalibrateError naming the file and field) a missing, not
// 4×4, non-finite or non-rigid matrix and residuals over 'limits' (a holdout_rms_m of −1,
// too few points to hold one out, passes).
Transform load_scanner_calibration(const std::filesystem::path& path,
                                   const ScannerResidualLimits& limits = {});

}  // namespace dentmark::calibrate
