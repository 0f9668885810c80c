#include "dentmark/firmware/calibrate/scanner_calibration.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>

#include "dentmark/common/atomic_file.h"
#include "dentmark/common/image/image_file.h"
#include "dentmark/common/ingest/read_scan_file.h"
#include "dentmark/firmware/calibrate/board_pose.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"
#include "dentmark/firmware/calibrate/calibration_yaml.h"
#include "dentmark/firmware/calibrate/image_pairs.h"
#include "dentmark/firmware/calibrate/input_digest.h"
#include "dentmark/firmware/calibrate/target_measurement.h"

namespace dentmark::calibrate {
namespace fs = std::filesystem;

std::vector<ScannerCaptureFiles> find_scanner_captures(const fs::path& dir) {
  const std::vector<ImagePair> pairs = find_image_pairs(dir);
  static const std::regex re(R"(^scan([0-9]{1,9})\.(ply|xyz|txt|pts|asc|csv|obj|stl)$)", std::regex::icase);
  std::map<long, fs::path> scans;
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator(dir, ec)) {
    if (!e.is_regular_file(ec)) continue;
    const std::string name = e.path().filename().string();
    std::smatch m;
    if (!std::regex_match(name, m, re)) continue;
    const long n = std::stol(m[1]);
    if (scans.count(n))
      throw CalibrateError(dir.string() + ": " + scans[n].filename().string() + " and " + name +
                           " both carry scan number " + std::to_string(n));
    scans[n] = e.path();
  }
  std::vector<ScannerCaptureFiles> out;
  for (const ImagePair& p : pairs) {
    const auto s = scans.find(p.number);
    if (s == scans.end())
      throw CalibrateError(p.left.string() + ": no scan" + p.name +
                           ".<ext> (ply, xyz, ...) for this image pair");
    out.push_back({p.name, s->second, p.left, p.right});
    scans.erase(s);
  }
  if (!scans.empty())
    throw CalibrateError(scans.begin()->second.string() + ": no image pair left" +
                         std::to_string(scans.begin()->first) + "/right" +
                         std::to_string(scans.begin()->first) + " for this scan");
  return out;
}

namespace {

cv::Mat grey(const fs::path& path, const track::StereoCalibration& stereo) {
  cv::Mat m;
  try {
    m = image::read_grey_image(path.string());
  } catch (const image::ImageError& e) {
    throw CalibrateError(e.what());
  }
  if (m.size() != stereo.size)
    throw CalibrateError(path.string() + ": " + std::to_string(m.cols) + "x" + std::to_string(m.rows) +
                         ", the stereo calibration is for " + std::to_string(stereo.size.width) + "x" +
                         std::to_string(stereo.size.height));
  return m;
}

std::vector<Eigen::Vector3d> scan_points(const fs::path& path, double scale) {
  ingest::ReadOptions o;
  o.scale_to_m = scale;
  ingest::Mesh mesh;
  try {
    mesh = ingest::read_scan_file(path.string(), o);
  } catch (const ingest::IngestError& e) {
    throw CalibrateError(e.what());
  }
  std::vector<Eigen::Vector3d> p;
  p.reserve(mesh.vertices.size());
  for (const Eigen::Vector3f& v : mesh.vertices)
    if (v.allFinite()) p.push_back(v.cast<double>());
  return p;
}

}  // namespace

ScannerCapture measure_scanner_capture(const ScannerTarget& target, const track::StereoCalibration& stereo,
                                       const ScannerCaptureFiles& files, double scale) {
  ScannerCapture c;
  c.name = files.name;
  const std::string scan_file = files.scan.string();
  ScanSpheres found;
  try {
    found = find_scan_spheres(scan_points(files.scan, scale), target.sphere_radius_m);
  } catch (const CalibrateError& e) {
    const std::string w = e.what();
    throw CalibrateError(w.rfind(scan_file, 0) == 0 ? w : scan_file + ": " + w);
  }
  c.not_spheres = found.rejected;
  const SphereMatch match = match_spheres(target, found.spheres, scan_file);
  c.match_rms_m = match.rms_m;
  const TargetMeasurement m =
      measure_target(target.board, stereo, grey(files.left, stereo), grey(files.right, stereo));
  if (!m.found)
    throw CalibrateError(files.left.string() + " / " + files.right.filename().string() + ": " + m.why);
  const BoardPose pose =
      refine_board_pose(target.board, stereo, m.pixels_left, m.pixels_right, m.T_camL_target);
  c.board_rms_px = pose.rms_px;
  c.board_view = {m.pixels_left, m.pixels_right, match.T_sls_board};
  for (std::size_t k = 0; k < match.ids.size(); ++k) {
    const int id = match.ids[k];
    c.ids.push_back(id);
    c.points_sls.push_back(found.spheres[k].centre_sls);
    c.points_camL.push_back(pose.T_camL_target * target.spheres_board[static_cast<std::size_t>(id)]);
  }
  return c;
}

ScannerCalibrationRun calibrate_scanner_captures(const fs::path& dir, const ScannerTarget& target,
                                                 const track::StereoCalibration& stereo, double scale) {
  if (!(scale > 0.0) || !std::isfinite(scale)) throw CalibrateError("--scan-unit: scale must be positive");
  ScannerCalibrationRun run;
  run.target = target;
  std::vector<fs::path> inputs;
  for (const ScannerCaptureFiles& f : find_scanner_captures(dir)) {
    run.captures.push_back(measure_scanner_capture(target, stereo, f, scale));
    inputs.insert(inputs.end(), {f.scan, f.left, f.right});
  }
  run.fit = fit_scanner(run.captures, target.board, stereo);
  run.inputs_sha256 =
      inputs_sha256("scanner target " + target.board.describe() + " radius " +
                        std::to_string(target.sphere_radius_m) + " scale " + std::to_string(scale) + '\0',
                    inputs);
  return run;
}

std::string scanner_calibration_yaml(const ScannerCalibrationRun& run) {
  const ScannerFit& f = run.fit;
  cv::FileStorage fs(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
  fs << "dentmark_scanner_calibration" << 1;
  fs << "T_camL_sls" << matrix_of(f.T_camL_sls);
  fs << "rms" << f.rms_m << "max_m" << f.max_m << "holdout_rms_m" << f.holdout_rms_m << "holdout_max_m"
     << f.holdout_max_m << "corners_rms_px" << f.corners_rms_px;
  fs << "captures" << f.captures << "points" << f.points;
  fs << "capture"
     << "[";
  for (const ScannerCapture& c : run.captures) {
    fs << "{"
       << "name" << c.name << "sphere_ids" << c.ids << "match_rms_m" << c.match_rms_m << "board_rms_px"
       << c.board_rms_px << "}";
  }
  fs << "]";
  fs << "target_pattern"
     << ("chessboard:" + std::to_string(run.target.board.cols) + "x" + std::to_string(run.target.board.rows));
  fs << "target_square_m" << run.target.board.square_m << "target_sphere_radius_m"
     << run.target.sphere_radius_m;
  cv::Mat s(static_cast<int>(run.target.spheres_board.size()), 3, CV_64F);
  for (std::size_t i = 0; i < run.target.spheres_board.size(); ++i)
    for (int k = 0; k < 3; ++k) s.at<double>(static_cast<int>(i), k) = run.target.spheres_board[i](k);
  fs << "target_spheres_board" << s;
  fs << "date" << run.created_utc << "inputs_sha256" << run.inputs_sha256 << "tool_version"
     << run.tool_version;
  return fs.releaseAndGetString();
}

std::string scanner_calibration_json(const ScannerCalibrationRun& run) {
  const ScannerFit& f = run.fit;
  nlohmann::json j;
  j["T_camL_sls"] = json_of(f.T_camL_sls);
  j["rms"] = f.rms_m;
  j["max_m"] = f.max_m;
  j["holdout_rms_m"] = f.holdout_rms_m;
  j["holdout_max_m"] = f.holdout_max_m;
  j["corners_rms_px"] = f.corners_rms_px;
  j["captures"] = f.captures;
  j["points"] = f.points;
  nlohmann::json cs = nlohmann::json::array();
  for (const ScannerCapture& c : run.captures)
    cs.push_back({{"name", c.name},
                  {"sphere_ids", c.ids},
                  {"match_rms_m", c.match_rms_m},
                  {"board_rms_px", c.board_rms_px}});
  j["capture"] = cs;
  j["target"] = run.target.board.describe();
  j["date"] = run.created_utc;
  j["inputs_sha256"] = run.inputs_sha256;
  j["tool_version"] = run.tool_version;
  return j.dump(2);
}

void write_scanner_calibration(const fs::path& path, const ScannerCalibrationRun& run) {
  try {
    files::write_atomically(path, scanner_calibration_yaml(run));
  } catch (const files::FileError& e) {
    throw CalibrateError(e.what());
  }
}

Transform load_scanner_calibration(const fs::path& path, const ScannerResidualLimits& limits) {
  const std::string file = path.string();
  cv::FileStorage fs = open_yaml(path);
  const Transform t = read_transform(fs["T_camL_sls"], file, "T_camL_sls");
  check_residual(fs, file, "rms", limits.max_rms_m);
  const cv::FileNode h = fs["holdout_rms_m"];
  if (!h.empty() && (h.isReal() || h.isInt()) && h.real() == -1.0) return t;
  check_residual(fs, file, "holdout_rms_m", limits.max_holdout_m);
  return t;
}

}  // namespace dentmark::calibrate
