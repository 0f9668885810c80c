#include "dentmark/firmware/calibrate/calibration_yaml.h"

#include <cmath>
#include <cstdio>
#include <opencv2/core/eigen.hpp>

#include "dentmark/common/yaml_file.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"

namespace dentmark::calibrate {

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
  return files::open_yaml_or_throw<CalibrateError>(path);
}

}  // namespace dentmark::calibrate
