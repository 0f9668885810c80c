#include "dentmark/firmware/calibrate/robot_fit.h"

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "dentmark/common/geometry/rigid_fit.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"

namespace dentmark::calibrate {
namespace {

void check(const RobotSamples& s) {
  const std::size_t n = s.target_points_tool.size();
  if (n < 3)
    throw CalibrateError("target_points_tool: " + std::to_string(n) + " points (need 3, not collinear)");
  if (s.samples.size() < 3)
    throw CalibrateError("samples: " + std::to_string(s.samples.size()) +
                         " poses (need at least 3; 15 recommended)");
  for (std::size_t i = 0; i < s.samples.size(); ++i) {
    const RobotSample& r = s.samples[i];
    const std::string where = "samples[" + std::to_string(i) + "]";
    if (r.points_camL.size() != n)
      throw CalibrateError(where + ".points_camL: " + std::to_string(r.points_camL.size()) +
                           " points, target_points_tool has " + std::to_string(n));
    if (!is_rigid(r.T_base_tool, 1e-6)) throw CalibrateError(where + ".T_base_tool: not a rigid transform");
    for (const auto& p : r.points_camL)
      if (!p.allFinite()) throw CalibrateError(where + ".points_camL: non-finite value");
  }
}

// Point pairs (camL → base) of the poses selected by 'use'.
void stack(const RobotSamples& s, const std::vector<std::size_t>& use, std::vector<Eigen::Vector3d>& from,
           std::vector<Eigen::Vector3d>& to) {
  from.clear();
  to.clear();
  for (std::size_t i : use)
    for (std::size_t j = 0; j < s.target_points_tool.size(); ++j) {
      from.push_back(s.samples[i].points_camL[j]);
      to.push_back(s.samples[i].T_base_tool * s.target_points_tool[j]);
    }
}

RigidFit fit_poses(const RobotSamples& s, const std::vector<std::size_t>& use) {
  std::vector<Eigen::Vector3d> from, to;
  stack(s, use, from, to);
  try {
    return fit_rigid(from, to);
  } catch (const GeometryError& e) {
    throw CalibrateError(std::string("robot fit: ") + e.what());
  }
}

double transfer_rms(const RobotSamples& s, std::size_t i, const Transform& T_base_camL) {
  double sum = 0.0;
  for (std::size_t j = 0; j < s.target_points_tool.size(); ++j)
    sum += (T_base_camL * s.samples[i].points_camL[j] - s.samples[i].T_base_tool * s.target_points_tool[j])
               .squaredNorm();
  return std::sqrt(sum / static_cast<double>(s.target_points_tool.size()));
}

void to_cv(const Transform& t, cv::Mat& r, cv::Mat& v) {
  cv::eigen2cv(Eigen::Matrix3d(t.linear()), r);
  cv::eigen2cv(Eigen::Vector3d(t.translation()), v);
}

Transform from_cv(const cv::Mat& r, const cv::Mat& v) {
  Eigen::Matrix3d re;
  Eigen::Vector3d te;
  cv::cv2eigen(r, re);
  cv::cv2eigen(v.reshape(1, 3), te);
  return make_transform(re, te);
}

// The cross-check (see robot_fit.h): target = OpenCV's camera, camL = its world.
void handeye(const RobotSamples& s, RobotFit& fit) {
  std::vector<cv::Mat> r_w2c, t_w2c, r_b2g, t_b2g;
  for (const RobotSample& r : s.samples) {
    const RigidFit pose = fit_rigid(s.target_points_tool, r.points_camL);  // T_camL_target
    cv::Mat a, b, c, d;                     // four buffers: the vectors share them
    to_cv(pose.T_to_from.inverse(), a, b);  // T_target_camL: "world to camera"
    r_w2c.push_back(a), t_w2c.push_back(b);
    to_cv(r.T_base_tool.inverse(), c, d);  // T_tool_base: "base to gripper"
    r_b2g.push_back(c), t_b2g.push_back(d);
  }
  cv::Mat r_b2w, t_b2w, r_g2c, t_g2c;
  try {
    cv::calibrateRobotWorldHandEye(r_w2c, t_w2c, r_b2g, t_b2g, r_b2w, t_b2w, r_g2c, t_g2c,
                                   cv::CALIB_ROBOT_WORLD_HAND_EYE_SHAH);
  } catch (const cv::Exception& e) {
    throw CalibrateError("hand-eye cross-check failed in OpenCV: " + e.err);
  }
  // Shah's closed form returns a rotation from a rank-one approximation; re-orthonormalise.
  auto proper = [](const cv::Mat& r) {
    cv::Mat w, u, vt;
    cv::SVDecomp(r, w, u, vt);
    cv::Mat p = u * vt;
    if (cv::determinant(p) < 0) p = -p;
    return p;
  };
  fit.T_base_camL_handeye = from_cv(proper(r_b2w), t_b2w).inverse();  // T_camL_base⁻¹
  fit.T_target_tool_handeye = from_cv(proper(r_g2c), t_g2c);
  fit.handeye_translation_diff_m =
      (fit.T_base_camL_handeye.translation() - fit.T_base_camL.translation()).norm();
  fit.handeye_rotation_diff_rad = rotation_angle_between(fit.T_base_camL_handeye, fit.T_base_camL);
}

}  // namespace

RobotFit fit_robot(const RobotSamples& s) {
  check(s);
  const std::size_t n = s.samples.size();
  std::vector<std::size_t> all(n);
  for (std::size_t i = 0; i < n; ++i) all[i] = i;
  RobotFit fit;
  const RigidFit full = fit_poses(s, all);
  fit.T_base_camL = full.T_to_from;
  fit.rms_m = full.rms;
  double sum = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    std::vector<std::size_t> rest;
    for (std::size_t k = 0; k < n; ++k)
      if (k != i) rest.push_back(k);
    const double e = transfer_rms(s, i, fit_poses(s, rest).T_to_from);
    fit.holdout_pose_rms_m.push_back(e);
    sum += e * e;
    fit.holdout_max_pose_m = std::max(fit.holdout_max_pose_m, e);
  }
  fit.holdout_rms_m = std::sqrt(sum / static_cast<double>(n));
  handeye(s, fit);
  return fit;
}

}  // namespace dentmark::calibrate
