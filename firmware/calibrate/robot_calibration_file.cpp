#include "dentmark/firmware/calibrate/robot_calibration_file.h"

#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>

#include "dentmark/common/atomic_file.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"
#include "dentmark/firmware/calibrate/calibration_yaml.h"

namespace dentmark::calibrate {
RobotSamples read_robot_samples(const std::filesystem::path& path) {
  const std::string file = path.string();
  cv::FileStorage fs = open_yaml(path);
  RobotSamples s;
  s.target_points_tool = read_points(fs["target_points_tool"], file, "target_points_tool");
  const cv::FileNode seq = fs["samples"];
  if (seq.empty() || !seq.isSeq()) throw CalibrateError(file + ": field samples is missing (a sequence)");
  int i = 0;
  for (const cv::FileNode& n : seq) {
    const std::string where = "samples[" + std::to_string(i++) + "]";
    RobotSample r;
    r.T_base_tool = read_transform(n["T_base_tool"], file, where + ".T_base_tool");
    r.points_camL = read_points(n["points_camL"], file, where + ".points_camL");
    if (r.points_camL.size() != s.target_points_tool.size())
      throw CalibrateError(file + ": field " + where + ".points_camL has " +
                           std::to_string(r.points_camL.size()) + " points, target_points_tool " +
                           std::to_string(s.target_points_tool.size()));
    s.samples.push_back(std::move(r));
  }
  return s;
}

void write_robot_samples(const std::filesystem::path& path, const RobotSamples& samples) {
  auto points = [](const std::vector<Eigen::Vector3d>& p) {
    cv::Mat m(static_cast<int>(p.size()), 3, CV_64F);
    for (std::size_t i = 0; i < p.size(); ++i)
      for (int k = 0; k < 3; ++k) m.at<double>(static_cast<int>(i), k) = p[i](k);
    return m;
  };
  cv::FileStorage fs(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
  fs << "target_points_tool" << points(samples.target_points_tool);
  fs << "samples"
     << "[";
  for (const RobotSample& r : samples.samples)
    fs << "{"
       << "T_base_tool" << matrix_of(r.T_base_tool) << "points_camL" << points(r.points_camL) << "}";
  fs << "]";
  try {
    files::write_atomically(path, fs.releaseAndGetString());
  } catch (const files::FileError& e) {
    throw CalibrateError(e.what());
  }
}

std::string robot_calibration_yaml(const RobotCalibrationRun& run) {
  const RobotFit& f = run.fit;
  cv::FileStorage fs(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
  fs << "dentmark_robot_calibration" << 1;
  fs << "T_base_camL" << matrix_of(f.T_base_camL);
  fs << "rms" << f.rms_m << "holdout_rms_m" << f.holdout_rms_m << "holdout_max_pose_m"
     << f.holdout_max_pose_m;
  fs << "handeye_translation_diff_m" << f.handeye_translation_diff_m << "handeye_rotation_diff_rad"
     << f.handeye_rotation_diff_rad;
  fs << "T_base_camL_handeye" << matrix_of(f.T_base_camL_handeye);
  fs << "poses" << run.poses << "points_per_pose" << run.points_per_pose;
  fs << "date" << run.created_utc << "inputs_sha256" << run.inputs_sha256 << "tool_version"
     << run.tool_version;
  if (run.target) {
    const TargetSpec& t = run.target->spec;
    fs << "target_pattern"
       << std::string(t.kind == TargetKind::kChessboard ? "chessboard:" : "charuco:") +
              std::to_string(t.cols) + "x" + std::to_string(t.rows);
    fs << "target_square_m" << t.square_m << "target_marker_m" << t.marker_m << "target_dictionary"
       << t.dictionary;
    fs << "T_tool_target" << matrix_of(run.target->T_tool_target);
  }
  return fs.releaseAndGetString();
}

std::string robot_calibration_json(const RobotCalibrationRun& run) {
  const RobotFit& f = run.fit;
  nlohmann::json j;
  j["T_base_camL"] = json_of(f.T_base_camL);
  j["rms"] = f.rms_m;
  j["holdout_rms_m"] = f.holdout_rms_m;
  j["holdout_max_pose_m"] = f.holdout_max_pose_m;
  j["holdout_pose_rms_m"] = f.holdout_pose_rms_m;
  j["handeye_translation_diff_m"] = f.handeye_translation_diff_m;
  j["handeye_rotation_diff_rad"] = f.handeye_rotation_diff_rad;
  j["T_base_camL_handeye"] = json_of(f.T_base_camL_handeye);
  j["poses"] = run.poses;
  j["points_per_pose"] = run.points_per_pose;
  j["date"] = run.created_utc;
  j["inputs_sha256"] = run.inputs_sha256;
  j["tool_version"] = run.tool_version;
  if (run.target) {
    j["target"] = run.target->spec.describe();
    j["T_tool_target"] = json_of(run.target->T_tool_target);
  }
  return j.dump(2);
}

void write_robot_calibration(const std::string& path, const RobotCalibrationRun& run) {
  try {
    files::write_atomically(path, robot_calibration_yaml(run));
  } catch (const files::FileError& e) {
    throw CalibrateError(e.what());
  }
}

Transform load_robot_calibration(const std::filesystem::path& path, const RobotResidualLimits& limits) {
  const std::string file = path.string();
  cv::FileStorage fs = open_yaml(path);
  const Transform t = read_transform(fs["T_base_camL"], file, "T_base_camL");
  check_residual(fs, file, "rms", limits.max_rms_m);
  check_residual(fs, file, "holdout_rms_m", limits.max_holdout_m);
  check_residual(fs, file, "handeye_translation_diff_m", limits.max_handeye_translation_m);
  return t;
}

}  // namespace dentmark::calibrate

namespace dentmark::calibrate {

std::optional<ToolTarget> load_robot_target(const std::filesystem::path& path) {
  const std::string file = path.string();
  cv::FileStorage fs = open_yaml(path);
  const cv::FileNode pattern = fs["target_pattern"];
  if (pattern.empty() || pattern.isNone()) return std::nullopt;
  if (!pattern.isString()) throw CalibrateError(file + ": field target_pattern is not a string");
  auto number = [&](const char* name) {
    const cv::FileNode n = fs[name];
    if (n.empty() || !(n.isReal() || n.isInt()))
      throw CalibrateError(file + ": field " + name + " is missing");
    return n.real();
  };
  ToolTarget t;
  try {
    const cv::FileNode dict = fs["target_dictionary"];
    t.spec = parse_target(pattern.string(), number("target_square_m"), number("target_marker_m"),
                          dict.isString() ? dict.string() : std::string());
  } catch (const CalibrateError& e) {
    throw CalibrateError(file + ": target: " + e.what());
  }
  t.T_tool_target = read_transform(fs["T_tool_target"], file, "T_tool_target");
  return t;
}

}  // namespace dentmark::calibrate
