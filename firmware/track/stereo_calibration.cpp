#include "dentmark/firmware/track/stereo_calibration.h"

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "dentmark/common/yaml_file.h"
#include "dentmark/firmware/track/track_error.h"
#include "matrix_node.h"

namespace dentmark::track {
namespace {

cv::Mat read_matrix(const cv::FileStorage& fs, const std::string& file, const char* name) {
  const cv::FileNode node = fs[name];
  if (node.empty() || node.isNone()) throw TrackError(file + ": field " + name + " is missing");
  detail::check_matrix_node(node, file, name, 64);
  cv::Mat m;
  try {
    node >> m;
  } catch (const cv::Exception&) {
    throw TrackError(file + ": field " + name + " is not an OpenCV matrix");
  }
  if (m.empty()) throw TrackError(file + ": field " + name + " is not an OpenCV matrix");
  if (m.channels() != 1) m = m.reshape(1);
  cv::Mat d;
  m.convertTo(d, CV_64F);
  if (!cv::checkRange(d)) throw TrackError(file + ": field " + name + " has a non-finite value");
  return d;
}

int read_positive_int(const cv::FileStorage& fs, const std::string& file, const char* name) {
  const cv::FileNode node = fs[name];
  if (node.empty() || !(node.isInt() || node.isReal()))
    throw TrackError(file + ": field " + name + " is missing");
  const double v = node.real();
  if (!(v >= 1 && v <= 65535) || v != std::floor(v))
    throw TrackError(file + ": field " + name + " must be a positive integer");
  return static_cast<int>(v);
}

CameraModel read_camera(const cv::FileStorage& fs, const std::string& file, const char* k_name,
                        const char* d_name) {
  CameraModel cam;
  const cv::Mat k = read_matrix(fs, file, k_name);
  if (k.rows != 3 || k.cols != 3) throw TrackError(file + ": field " + k_name + " must be 3x3");
  if (!(k.at<double>(0, 0) > 0 && k.at<double>(1, 1) > 0) || std::abs(k.at<double>(2, 2) - 1.0) > 1e-9 ||
      k.at<double>(2, 0) != 0 || k.at<double>(2, 1) != 0 || k.at<double>(1, 0) != 0)
    throw TrackError(file + ": field " + k_name + " is not a camera matrix [fx s cx; 0 fy cy; 0 0 1]");
  cam.K = cv::Matx33d(k);
  const cv::FileNode dn = fs[d_name];
  if (dn.empty() || dn.isNone()) throw TrackError(file + ": field " + d_name + " is missing");
  const cv::Mat d = read_matrix(fs, file, d_name);
  const int n = static_cast<int>(d.total());
  if (n != 4 && n != 5 && n != 8 && n != 12 && n != 14)
    throw TrackError(file + ": field " + d_name + " must hold 4, 5, 8, 12 or 14 coefficients, has " +
                     std::to_string(n));
  cam.D = d.reshape(1, 1).clone();
  return cam;
}

// A recorded residual (pixels): absent is allowed unless 'required'; −1 means "not
// computed" where 'may_be_unset'.
void check_residual(const cv::FileStorage& fs, const std::string& file, const char* name, double limit,
                    bool required, bool may_be_unset) {
  const cv::FileNode node = fs[name];
  if (node.empty() || node.isNone()) {
    if (required) throw TrackError(file + ": field " + name + " is missing");
    return;
  }
  if (!(node.isReal() || node.isInt())) throw TrackError(file + ": field " + name + " is not a number");
  const double v = node.real();
  if (may_be_unset && v == -1.0) return;
  if (!std::isfinite(v) || v < 0.0)
    throw TrackError(file + ": field " + name + " is not a residual (" + std::to_string(v) + ")");
  if (v > limit) {
    char b[160];
    std::snprintf(b, sizeof b, ": field %s is %.3f px, over the limit of %.3f px: recalibrate", name, v,
                  limit);
    throw TrackError(file + b);
  }
}

void check_residuals(const cv::FileStorage& fs, const std::string& file, const StereoResidualLimits& limits) {
  const bool ours = !fs["dentmark_stereo_calibration"].empty();
  check_residual(fs, file, "rms_px", limits.max_rms_px, ours, false);
  check_residual(fs, file, "epipolar_rectified_px", limits.max_epipolar_px, ours, false);
  check_residual(fs, file, "holdout_rms_px", limits.max_holdout_px, ours, true);
}

}  // namespace

StereoCalibration load_stereo_calibration(const std::filesystem::path& path,
                                          const StereoResidualLimits& limits) {
  const std::string file = path.string();
  cv::FileStorage fs = files::open_yaml_or_throw<TrackError>(path);
  StereoCalibration c;
  c.size = {read_positive_int(fs, file, "image_width"), read_positive_int(fs, file, "image_height")};
  c.left = read_camera(fs, file, "K1", "D1");
  c.right = read_camera(fs, file, "K2", "D2");
  cv::Mat r = read_matrix(fs, file, "R");
  if (r.total() == 3) {
    cv::Mat rm;
    cv::Rodrigues(r.reshape(1, 3), rm);
    r = rm;
  }
  if (r.rows != 3 || r.cols != 3) throw TrackError(file + ": field R must be 3x3 or a rotation vector");
  Eigen::Matrix3d re;
  cv::cv2eigen(r, re);
  if ((re.transpose() * re - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-3)
    throw TrackError(file + ": field R is not a rotation (not orthonormal: |R^T R - I| > 1e-3)");
  if (std::abs(re.determinant() - 1.0) > 1e-2)
    throw TrackError(file + ": field R is not a rotation (determinant " + std::to_string(re.determinant()) +
                     ", not +1)");
  // Re-orthonormalise: files carry rounded values.
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(re, Eigen::ComputeFullU | Eigen::ComputeFullV);
  re = svd.matrixU() * svd.matrixV().transpose();
  const cv::Mat t = read_matrix(fs, file, "T");
  if (t.total() != 3) throw TrackError(file + ": field T must have 3 elements");
  const Eigen::Vector3d te(t.at<double>(0), t.at<double>(1), t.at<double>(2));
  if (te.norm() < 1e-6) throw TrackError(file + ": field T is zero (no baseline)");
  c.T_camR_camL = Transform::Identity();
  c.T_camR_camL.linear() = re;
  c.T_camR_camL.translation() = te;
  check_residuals(fs, file, limits);
  return c;
}

std::vector<cv::Point2f> StereoCalibration::project(Cam c, const std::vector<Eigen::Vector3d>& p_camL) const {
  std::vector<cv::Point3d> obj;
  obj.reserve(p_camL.size());
  const Transform t = c == Cam::kLeft ? Transform::Identity() : T_camR_camL;
  for (const auto& p : p_camL) {
    const Eigen::Vector3d q = t * p;
    obj.emplace_back(q.x(), q.y(), q.z());
  }
  std::vector<cv::Point2f> img;
  if (obj.empty()) return img;
  std::vector<cv::Point2d> imgd;
  cv::projectPoints(obj, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), camera(c).K, camera(c).D, imgd);
  img.reserve(imgd.size());
  for (const auto& q : imgd) img.emplace_back(static_cast<float>(q.x), static_cast<float>(q.y));
  return img;
}

std::vector<cv::Point2d> StereoCalibration::normalize(Cam c, const std::vector<cv::Point2f>& pixels) const {
  std::vector<cv::Point2d> out;
  if (pixels.empty()) return out;
  std::vector<cv::Point2d> in(pixels.begin(), pixels.end());
  // More iterations than OpenCV's default 5: strong distortion needs them for 0.01 px.
  cv::undistortPoints(in, out, camera(c).K, camera(c).D, cv::noArray(), cv::noArray(),
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-12));
  return out;
}

Triangulation triangulate(const StereoCalibration& calib, const cv::Point2d& nl, const cv::Point2d& nr) {
  const Eigen::Matrix3d r = calib.T_camR_camL.linear();
  const Eigen::Vector3d t = calib.T_camR_camL.translation();
  Eigen::Matrix<double, 3, 4> pr;
  pr << r, t;
  Eigen::Matrix<double, 3, 4> pl = Eigen::Matrix<double, 3, 4>::Zero();
  pl.leftCols<3>().setIdentity();
  Eigen::Matrix4d a;
  a.row(0) = nl.x * pl.row(2) - pl.row(0);
  a.row(1) = nl.y * pl.row(2) - pl.row(1);
  a.row(2) = nr.x * pr.row(2) - pr.row(0);
  a.row(3) = nr.y * pr.row(2) - pr.row(1);
  const Eigen::JacobiSVD<Eigen::Matrix4d> svd(a, Eigen::ComputeFullV);
  Eigen::Vector4d h = svd.matrixV().col(3);
  Eigen::Vector3d p = h.head<3>() / (std::abs(h(3)) > 1e-15 ? h(3) : 1e-15);

  // Gauss-Newton on the reprojection error, weighted by each camera's focal length.
  const double fl = calib.left.K(0, 0), fr = calib.right.K(0, 0);
  for (int it = 0; it < 3; ++it) {
    Eigen::Matrix<double, 4, 3> j;
    Eigen::Vector4d e;
    const Eigen::Vector3d q = r * p + t;
    if (p.z() <= 1e-9 || q.z() <= 1e-9) break;
    e << fl * (p.x() / p.z() - nl.x), fl * (p.y() / p.z() - nl.y), fr * (q.x() / q.z() - nr.x),
        fr * (q.y() / q.z() - nr.y);
    Eigen::Matrix<double, 2, 3> dl, dq;
    dl << 1 / p.z(), 0, -p.x() / (p.z() * p.z()), 0, 1 / p.z(), -p.y() / (p.z() * p.z());
    dq << 1 / q.z(), 0, -q.x() / (q.z() * q.z()), 0, 1 / q.z(), -q.y() / (q.z() * q.z());
    j.topRows<2>() = fl * dl;
    j.bottomRows<2>() = fr * dq * r;
    const Eigen::Vector3d step = (j.transpose() * j).ldlt().solve(-j.transpose() * e);
    if (!step.allFinite()) break;
    p += step;
    if (step.norm() < 1e-10) break;
  }
  Triangulation out;
  out.p_camL = p;
  const Eigen::Vector3d q = r * p + t;
  const double el = fl * std::hypot(p.x() / p.z() - nl.x, p.y() / p.z() - nl.y);
  const double er = fr * std::hypot(q.x() / q.z() - nr.x, q.y() / q.z() - nr.y);
  out.reprojection_px = (p.z() > 0 && q.z() > 0) ? std::max(el, er) : 1e9;
  return out;
}

}  // namespace dentmark::track
