#include "dentmark/firmware/calibrate/board_pose.h"

#include <Eigen/Dense>
#include <cmath>

namespace dentmark::calibrate {
namespace {

// Residuals (pixels) of every corner in both cameras for the pose T.
Eigen::VectorXd residuals(const std::vector<Eigen::Vector3d>& board,
                          const std::vector<cv::Point2d> observed[2], const Transform T_cam_camL[2],
                          const double focal[2], const Transform& T) {
  Eigen::VectorXd r(static_cast<Eigen::Index>(4 * board.size()));
  Eigen::Index k = 0;
  for (int c = 0; c < 2; ++c)
    for (std::size_t j = 0; j < board.size(); ++j) {
      const Eigen::Vector3d p = T_cam_camL[c] * (T * board[j]);
      r(k++) = focal[c] * (p.x() / p.z() - observed[c][j].x);
      r(k++) = focal[c] * (p.y() / p.z() - observed[c][j].y);
    }
  return r;
}

// T perturbed by a small motion δ = (rotation vector, translation) applied on the left.
Transform perturbed(const Transform& T, const Eigen::Matrix<double, 6, 1>& d) {
  return make_transform_rotvec(d.head<3>(), d.tail<3>()) * T;
}

}  // namespace

BoardPose refine_board_pose(const TargetSpec& target, const track::StereoCalibration& stereo,
                            const std::vector<cv::Point2f>& pixels_left,
                            const std::vector<cv::Point2f>& pixels_right, const Transform& start) {
  std::vector<Eigen::Vector3d> board;
  for (int id = 0; id < target.corner_count(); ++id) {
    const cv::Point3f c = target.corner(id);
    board.emplace_back(c.x, c.y, c.z);
  }
  const std::vector<cv::Point2d> observed[2] = {stereo.normalize(track::Cam::kLeft, pixels_left),
                                                stereo.normalize(track::Cam::kRight, pixels_right)};
  const Transform T_cam_camL[2] = {Transform::Identity(), stereo.T_camR_camL};
  const double focal[2] = {0.5 * (stereo.left.K(0, 0) + stereo.left.K(1, 1)),
                           0.5 * (stereo.right.K(0, 0) + stereo.right.K(1, 1))};
  Transform T = start;
  Eigen::VectorXd r = residuals(board, observed, T_cam_camL, focal, T);
  for (int it = 0; it < 20; ++it) {
    // Jacobian by central differences (6 parameters, a few hundred residuals).
    Eigen::MatrixXd J(r.size(), 6);
    for (int p = 0; p < 6; ++p) {
      Eigen::Matrix<double, 6, 1> d = Eigen::Matrix<double, 6, 1>::Zero();
      const double h = p < 3 ? 1e-6 : 1e-6;  // rad, m
      d(p) = h;
      J.col(p) = (residuals(board, observed, T_cam_camL, focal, perturbed(T, d)) -
                  residuals(board, observed, T_cam_camL, focal, perturbed(T, -d))) /
                 (2.0 * h);
    }
    const Eigen::Matrix<double, 6, 1> step = (J.transpose() * J).ldlt().solve(-J.transpose() * r);
    if (!step.allFinite()) break;
    const Transform next = perturbed(T, step);
    const Eigen::VectorXd rn = residuals(board, observed, T_cam_camL, focal, next);
    if (rn.squaredNorm() > r.squaredNorm()) break;  // no longer improving
    T = next, r = rn;
    if (step.norm() < 1e-10) break;
  }
  BoardPose out;
  out.T_camL_target = T;
  out.rms_px = std::sqrt(r.squaredNorm() / static_cast<double>(r.size() / 2));
  return out;
}

}  // namespace dentmark::calibrate
