#include "dentmark/firmware/track/pose_refine.h"

#include <Eigen/Dense>
#include <cmath>

namespace dentmark::track {

PoseRefineResult refine_pose(const StereoCalibration& calib, const Transform& start,
                             const std::vector<Eigen::Vector3d>& reference,
                             const std::vector<cv::Point2d>& n_left, const std::vector<cv::Point2d>& n_right,
                             int iterations, double huber_px) {
  const Eigen::Matrix3d rr = calib.T_camR_camL.linear();
  const Eigen::Vector3d tr = calib.T_camR_camL.translation();
  const double fl = calib.left.K(0, 0), fr = calib.right.K(0, 0);
  Transform m = start;
  double rms = 0.0;
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
  for (int it = 0; it <= iterations; ++it) {
    Eigen::Matrix<double, 6, 6> h = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
    double sq = 0.0;
    int count = 0;
    for (std::size_t i = 0; i < reference.size(); ++i) {
      const Eigen::Vector3d p = m * reference[i];
      // Left perturbation p → p + δω × p + δt: ∂p/∂(δω, δt) = [−[p]×, I].
      Eigen::Matrix<double, 3, 6> dp;
      dp.leftCols<3>() << 0, p.z(), -p.y(), -p.z(), 0, p.x(), p.y(), -p.x(), 0;
      dp.rightCols<3>().setIdentity();
      for (int cam = 0; cam < 2; ++cam) {
        const Eigen::Vector3d q = cam == 0 ? p : Eigen::Vector3d(rr * p + tr);
        if (q.z() <= 1e-6) continue;
        const double f = cam == 0 ? fl : fr;
        const cv::Point2d& n = cam == 0 ? n_left[i] : n_right[i];
        const Eigen::Vector2d e(f * (q.x() / q.z() - n.x), f * (q.y() / q.z() - n.y));
        Eigen::Matrix<double, 2, 3> dq;
        dq << f / q.z(), 0, -f * q.x() / (q.z() * q.z()), 0, f / q.z(), -f * q.y() / (q.z() * q.z());
        const Eigen::Matrix<double, 2, 6> j =
            cam == 0 ? Eigen::Matrix<double, 2, 6>(dq * dp) : Eigen::Matrix<double, 2, 6>(dq * rr * dp);
        const double en = e.norm();
        const double w = en <= huber_px ? 1.0 : huber_px / en;
        h += w * j.transpose() * j;
        g += w * j.transpose() * e;
        sq += e.squaredNorm();
        ++count;
      }
    }
    rms = count ? std::sqrt(sq / count) : 0.0;
    information = h;
    if (it == iterations || count < 6) break;
    const Eigen::Matrix<double, 6, 1> step = h.ldlt().solve(-g);
    if (!step.allFinite()) break;
    Transform d = Transform::Identity();
    const double a = step.head<3>().norm();
    if (a > 0) d.linear() = Eigen::AngleAxisd(a, step.head<3>() / a).toRotationMatrix();
    d.translation() = step.tail<3>();
    m = d * m;
    if (step.norm() < 1e-12) break;
  }
  return {m, rms, information};
}

}  // namespace dentmark::track
