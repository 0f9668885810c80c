#include "dentmark/sim/calibration/calibration_scene.h"

#include <cmath>
#include <numbers>
#include <opencv2/core/eigen.hpp>
#include <stdexcept>

#include "dentmark/common/yaml_file.h"

namespace dentmark::sim::calibration {
namespace {

cv::Mat required(const cv::FileStorage& fs, const std::string& file, const char* name, int rows, int cols) {
  cv::Mat m;
  fs[name] >> m;
  if (m.empty()) throw std::runtime_error(file + ": field " + std::string(name) + " is missing");
  m.convertTo(m, CV_64F);
  if (m.total() != static_cast<std::size_t>(rows * cols))
    throw std::runtime_error(file + ": field " + std::string(name) + " must have " +
                             std::to_string(rows * cols) + " values");
  return m.reshape(1, rows);
}

Transform transform_of(const cv::Mat& m) {
  Eigen::Matrix4d e;
  cv::cv2eigen(m, e);
  Transform t = Transform::Identity();
  t.matrix() = e;
  return t;
}

double number(const cv::FileStorage& fs, const std::string& file, const char* name) {
  const cv::FileNode n = fs[name];
  if (n.empty() || !(n.isReal() || n.isInt()))
    throw std::runtime_error(file + ": field " + std::string(name) + " is missing (a number)");
  return n.real();
}

}  // namespace

CalibrationScene read_calibration_scene(const std::filesystem::path& path) {
  const std::string file = path.string();
  cv::FileStorage fs = files::open_yaml(path);
  CalibrationScene s;
  s.rig.size = cv::Size(static_cast<int>(number(fs, file, "image_width")),
                        static_cast<int>(number(fs, file, "image_height")));
  s.rig.left.K = cv::Matx33d(required(fs, file, "K1", 3, 3));
  s.rig.right.K = cv::Matx33d(required(fs, file, "K2", 3, 3));
  s.rig.left.D = required(fs, file, "D1", 1, 5);
  s.rig.right.D = required(fs, file, "D2", 1, 5);
  Eigen::Matrix3d r;
  Eigen::Vector3d t;
  cv::cv2eigen(required(fs, file, "R", 3, 3), r);
  cv::cv2eigen(required(fs, file, "T", 3, 1), t);
  s.rig.T_camR_camL = make_transform(r, t);
  s.T_base_camL = transform_of(required(fs, file, "T_base_camL", 4, 4));
  s.T_tool_target = transform_of(required(fs, file, "T_tool_target", 4, 4));
  s.target.cols = static_cast<int>(number(fs, file, "target_cols"));
  s.target.rows = static_cast<int>(number(fs, file, "target_rows"));
  s.target.square = number(fs, file, "target_square");
  s.imaging.blur_sigma = number(fs, file, "blur_sigma");
  s.imaging.noise_sigma = number(fs, file, "noise_sigma");
  if (s.target.cols < 2 || s.target.rows < 2 || !(s.target.square > 0.0) || s.rig.size.width <= 0 ||
      s.rig.size.height <= 0)
    throw std::runtime_error(file + ": target or image size out of range");
  return s;
}

void write_calibration_scene(const CalibrationScene& s, const std::filesystem::path& path) {
  sim::stereo::write_stereo_yaml(s.rig, path);  // image size, K1 D1 K2 D2 R T
  cv::FileStorage fs(path.string(), cv::FileStorage::APPEND);
  if (!fs.isOpened()) throw std::runtime_error(path.string() + ": cannot open for writing");
  cv::Mat a, b;
  cv::eigen2cv(Eigen::Matrix4d(s.T_base_camL.matrix()), a);
  cv::eigen2cv(Eigen::Matrix4d(s.T_tool_target.matrix()), b);
  fs << "T_base_camL" << a << "T_tool_target" << b;
  fs << "target_cols" << s.target.cols << "target_rows" << s.target.rows << "target_square"
     << s.target.square;
  fs << "blur_sigma" << s.imaging.blur_sigma << "noise_sigma" << s.imaging.noise_sigma;
}

CalibrationScene twin_calibration_scene() {
  constexpr double kDistance = 2.8, kBaseline = 0.5, kFocal = 1740.0;
  CalibrationScene s;
  s.rig = sim::stereo::make_rig({1280, 1024}, kFocal, kBaseline, std::atan(0.5 * kBaseline / kDistance));
  // workcell.cpp: the base 0.6 m in front of the door centre at B, axes along camL.
  const Eigen::Vector3d centre_B(0.5 * kBaseline - 0.17, 0.1, kDistance);
  s.T_base_camL = make_transform_rotvec(Eigen::Vector3d::Zero(), -(centre_B - Eigen::Vector3d(0, 0, 0.6)));
  // The board 20 mm in front of the tool point, centred on the tool axis, its corner
  // grid along the tool's x and y.
  s.target = ChessboardTarget{7, 6, 0.03};
  s.T_tool_target = make_transform_rotvec(
      Eigen::Vector3d::Zero(), Eigen::Vector3d(-0.5 * (s.target.cols - 1) * s.target.square,
                                               -0.5 * (s.target.rows - 1) * s.target.square, 0.02));
  return s;
}

}  // namespace dentmark::sim::calibration
