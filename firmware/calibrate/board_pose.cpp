#include "dentmark/firmware/calibrate/board_pose.h"

#include <Eigen/Dense>
#include <cmath>

namespace dentmark::calibrate {
namespace {

// One view's corners undistorted and normalised, with the target's pose in frame x.
struct NormalisedView {
  std::vector<cv::Point2d> observed[2];
  Transform T_x_target;
};

struct Cameras {
  Transform T_cam_camL[2];
  double focal[2];
};

// Residuals (pixels) of every corner of every view in both cameras for T_camL_x.
Eigen::VectorXd residuals(const std::vector<Eigen::Vector3d>& board, const std::vector<NormalisedView>& views,
                          const Cameras& cams, const Transform& T_camL_x) {
  Eigen::VectorXd r(static_cast<Eigen::Index>(4 * board.size() * views.size()));
  Eigen::Index k = 0;
  for (const NormalisedView& v : views) {
    const Transform T_camL_target = T_camL_x * v.T_x_target;
    for (int c = 0; c < 2; ++c)
      for (std::size_t j = 0; j < board.size(); ++j) {
        const Eigen::Vector3d p = cams.T_cam_camL[c] * (T_camL_target * board[j]);
        r(k++) = cams.focal[c] * (p.x() / p.z() - v.observed[c][j].x);
        r(k++) = cams.focal[c] * (p.y() / p.z() - v.observed[c][j].y);
      }
  }
  return r;
}

// T perturbed by a small motion δ = (rotation vector, translation) applied on the left.
Transform perturbed(const Transform& T, const Eigen::Matrix<double, 6, 1>& d) {
  return make_transform_rotvec(d.head<3>(), d.tail<3>()) * T;
}

}  // namespace

ChainedPose refine_chained_pose(const TargetSpec& target, const track::StereoCalibration& stereo,
                                const std::vector<BoardView>& views, const Transform& start) {
  std::vector<Eigen::Vector3d> board;
  for (int id = 0; id < target.corner_count(); ++id) {
    const cv::Point3f c = target.corner(id);
    board.emplace_back(c.x, c.y, c.z);
  }
  std::vector<NormalisedView> normalised;
  for (const BoardView& v : views)
    normalised.push_back({{stereo.normalize(track::Cam::kLeft, v.pixels_left),
                           stereo.normalize(track::Cam::kRight, v.pixels_right)},
                          v.T_x_target});
  const Cameras cams{{Transform::Identity(), stereo.T_camR_camL},
                     {0.5 * (stereo.left.K(0, 0) + stereo.left.K(1, 1)),
                      0.5 * (stereo.right.K(0, 0) + stereo.right.K(1, 1))}};
  Transform T = start;
  Eigen::VectorXd r = residuals(board, normalised, cams, T);
  for (int it = 0; it < 20; ++it) {
    // Jacobian by central differences (6 parameters, a few hundred residuals a view).
    Eigen::MatrixXd J(r.size(), 6);
    for (int p = 0; p < 6; ++p) {
      Eigen::Matrix<double, 6, 1> d = Eigen::Matrix<double, 6, 1>::Zero();
      const double h = 1e-6;  // rad, m
      d(p) = h;
      J.col(p) = (residuals(board, normalised, cams, perturbed(T, d)) -
                  residuals(board, normalised, cams, perturbed(T, -d))) /
                 (2.0 * h);
    }
    const Eigen::Matrix<double, 6, 1> step = (J.transpose() * J).ldlt().solve(-J.transpose() * r);
    if (!step.allFinite()) break;
    const Transform next = perturbed(T, step);
    const Eigen::VectorXd rn = residuals(board, normalised, cams, next);
    if (rn.squaredNorm() > r.squaredNorm()) break;  // no longer improving
    T = next, r = rn;
    if (step.norm() < 1e-10) break;
  }
  ChainedPose out;
  out.T_camL_x = T;
  out.rms_px = r.size() > 0 ? std::sqrt(r.squaredNorm() / static_cast<double>(r.size() / 2)) : 0.0;
  return out;
}

BoardPose refine_board_pose(const TargetSpec& target, const track::StereoCalibration& stereo,
                            const std::vector<cv::Point2f>& pixels_left,
                            const std::vector<cv::Point2f>& pixels_right, const Transform& start) {
  const ChainedPose p = refine_chained_pose(
      target, stereo, {BoardView{pixels_left, pixels_right, Transform::Identity()}}, start);
  return {p.T_camL_x, p.rms_px};
}

}  // namespace dentmark::calibrate
