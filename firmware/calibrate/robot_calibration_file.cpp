#include "dentmark/firmware/calibrate/robot_calibration_file.h"

#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>

#include "dentmark/common/atomic_file.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"

namespace dentmark::calibrate {
namespace {

cv::Mat read_matrix(const cv::FileNode& node, const std::string& file, const std::string& name, int rows,
                    int cols) {
  if (node.empty() || node.isNone()) throw CalibrateError(file + ": field " + name + " is missing");
  if (node.isMap()) {  // guard the declared size before OpenCV allocates it
    const cv::FileNode r = node["rows"], c = node["cols"], d = node["data"];
    if (r.empty() || c.empty() || d.empty() || !r.isInt() || !c.isInt() || !d.isSeq() ||
        static_cast<double>(static_cast<int>(r)) * static_cast<int>(c) != static_cast<double>(d.size()) ||
        d.size() > 3000000)
      throw CalibrateError(file + ": field " + name + " is not an OpenCV matrix");
  }
  cv::Mat m;
  try {
    node >> m;
  } catch (const cv::Exception&) {
    throw CalibrateError(file + ": field " + name + " is not an OpenCV matrix");
  }
  if (m.empty()) throw CalibrateError(file + ": field " + name + " is not an OpenCV matrix");
  cv::Mat d;
  m.reshape(1).convertTo(d, CV_64F);
  if ((rows > 0 && d.rows != rows) || d.cols != cols)
    throw CalibrateError(file + ": field " + name + " must be " + (rows > 0 ? std::to_string(rows) : "N") +
                         "x" + std::to_string(cols) + ", is " + std::to_string(d.rows) + "x" +
                         std::to_string(d.cols));
  if (!cv::checkRange(d)) throw CalibrateError(file + ": field " + name + " has a non-finite value");
  return d;
}

// A 4×4 rigid transform [R t; 0 0 0 1].
Transform read_transform(const cv::FileNode& node, const std::string& file, const std::string& name) {
  const cv::Mat m = read_matrix(node, file, name, 4, 4);
  Eigen::Matrix4d e;
  cv::cv2eigen(m, e);
  const Eigen::Matrix3d r = e.topLeftCorner<3, 3>();
  if ((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-3)
    throw CalibrateError(file + ": field " + name +
                         " is not rigid (rotation not orthonormal: |R^T R - I| > 1e-3)");
  if (std::abs(r.determinant() - 1.0) > 1e-2)
    throw CalibrateError(file + ": field " + name + " is not rigid (rotation determinant " +
                         std::to_string(r.determinant()) + ", not +1)");
  if ((e.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9)
    throw CalibrateError(file + ": field " + name + " is not rigid (last row is not 0 0 0 1)");
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(r, Eigen::ComputeFullU | Eigen::ComputeFullV);
  return make_transform(svd.matrixU() * svd.matrixV().transpose(), e.topRightCorner<3, 1>());
}

std::vector<Eigen::Vector3d> read_points(const cv::FileNode& node, const std::string& file,
                                         const std::string& name) {
  const cv::Mat m = read_matrix(node, file, name, 0, 3);
  std::vector<Eigen::Vector3d> p;
  for (int i = 0; i < m.rows; ++i) p.emplace_back(m.at<double>(i, 0), m.at<double>(i, 1), m.at<double>(i, 2));
  return p;
}

cv::Mat matrix_of(const Transform& t) {
  cv::Mat m;
  cv::eigen2cv(Eigen::Matrix4d(t.matrix()), m);
  return m;
}

nlohmann::json json_of(const Transform& t) {
  nlohmann::json rows = nlohmann::json::array();
  for (int i = 0; i < 4; ++i)
    rows.push_back({t.matrix()(i, 0), t.matrix()(i, 1), t.matrix()(i, 2), t.matrix()(i, 3)});
  return rows;
}

void check_residual(const cv::FileStorage& fs, const std::string& file, const char* name, double limit) {
  const cv::FileNode node = fs[name];
  if (node.empty() || node.isNone()) throw CalibrateError(file + ": field " + name + " is missing");
  if (!(node.isReal() || node.isInt())) throw CalibrateError(file + ": field " + name + " is not a number");
  const double v = node.real();
  if (!std::isfinite(v) || v < 0.0) throw CalibrateError(file + ": field " + name + " is not a residual");
  if (v > limit) {
    char b[160];
    std::snprintf(b, sizeof b, ": field %s is %.3f mm, over the limit of %.3f mm: recalibrate", name, v * 1e3,
                  limit * 1e3);
    throw CalibrateError(file + b);
  }
}

cv::FileStorage open_yaml(const std::filesystem::path& path) {
  const std::string file = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw CalibrateError(file + ": no such file");
  cv::FileStorage fs;
  try {
    if (!fs.open(file, cv::FileStorage::READ)) throw CalibrateError(file + ": cannot open");
  } catch (const cv::Exception& e) {
    throw CalibrateError(file + ": not readable as OpenCV FileStorage YAML (" + e.err + ")");
  }
  return fs;
}

}  // namespace

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
