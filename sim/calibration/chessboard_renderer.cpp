#include "dentmark/sim/calibration/chessboard_renderer.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

namespace dentmark::sim::calibration {
namespace {

const sim::stereo::PinholeCamera& camera(const sim::stereo::StereoRig& rig, sim::stereo::Eye eye) {
  return eye == sim::stereo::Eye::kLeft ? rig.left : rig.right;
}

// Grey level of the board's plane at (x, y) in the target frame.
double shade(const ChessboardTarget& t, const TargetImaging& im, double x, double y) {
  const double s = t.square;
  // Squares span [-s, cols·s] × [-s, rows·s]; one square of white border around them.
  if (x < -2.0 * s || y < -2.0 * s || x > (t.cols + 1) * s || y > (t.rows + 1) * s) return im.background;
  if (x < -s || y < -s || x > t.cols * s || y > t.rows * s) return im.white;
  const long a = static_cast<long>(std::floor(x / s)), b = static_cast<long>(std::floor(y / s));
  return ((a + b) & 1) == 0 ? im.black : im.white;
}

}  // namespace

ChessboardRenderer::ChessboardRenderer(sim::stereo::StereoRig rig, ChessboardTarget target)
    : rig_(std::move(rig)), target_(target) {
  for (int e = 0; e < 2; ++e) {
    normalized_[e] =
        sim::stereo::normalized_pixel_grid(camera(rig_, static_cast<sim::stereo::Eye>(e)), rig_.size);
  }
}

cv::Mat ChessboardRenderer::render(sim::stereo::Eye eye, const Transform& T_camL_target,
                                   const TargetImaging& im, cv::RNG& rng) const {
  const sim::stereo::PinholeCamera& cam = camera(rig_, eye);
  const Transform T_cam_target =
      (eye == sim::stereo::Eye::kLeft ? Transform::Identity() : rig_.T_camR_camL) * T_camL_target;
  cv::Mat1f img(rig_.size, static_cast<float>(im.background));
  // The board's outline (with border) projected: only pixels inside its bounding box
  // see the board.
  const double s = target_.square;
  std::vector<cv::Point3d> outline;
  bool in_front = true;  // a board reaching behind the camera is not drawn
  for (double x : {-2.0 * s, (target_.cols + 1) * s})
    for (double y : {-2.0 * s, (target_.rows + 1) * s}) {
      const Eigen::Vector3d p = T_cam_target * Eigen::Vector3d(x, y, 0.0);
      in_front = in_front && p.z() > 0.05;
      outline.emplace_back(p.x(), p.y(), p.z());
    }
  cv::Rect box;
  if (in_front) {
    std::vector<cv::Point2d> px;
    cv::projectPoints(outline, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), cam.K, cam.D, px);
    std::vector<cv::Point2f> pf;
    for (const auto& p : px)
      pf.emplace_back(static_cast<float>(std::clamp(p.x, -1e5, 1e5)),
                      static_cast<float>(std::clamp(p.y, -1e5, 1e5)));
    box = cv::boundingRect(pf);
    box.x -= 3, box.y -= 3, box.width += 6, box.height += 6;
    box &= cv::Rect(0, 0, rig_.size.width, rig_.size.height);
  }

  // Plane z = 0 of the target: normalised n ~ H (x, y, 1), H = [r1 r2 t]; back by H⁻¹.
  Eigen::Matrix3d h;
  h.col(0) = T_cam_target.linear().col(0);
  h.col(1) = T_cam_target.linear().col(1);
  h.col(2) = T_cam_target.translation();
  const Eigen::Matrix3d hi = h.inverse();
  const double dx = 1.0 / cam.K(0, 0), dy = 1.0 / cam.K(1, 1);  // one pixel in normalised units
  constexpr int kSub = 4;
  for (int v = box.y; v < box.y + box.height; ++v)
    for (int u = box.x; u < box.x + box.width; ++u) {
      const cv::Vec2f n0 = normalized_[static_cast<int>(eye)].at<cv::Vec2f>(v, u);
      double sum = 0.0;
      for (int a = 0; a < kSub; ++a)
        for (int b = 0; b < kSub; ++b) {
          const Eigen::Vector3d n(n0[0] + ((b + 0.5) / kSub - 0.5) * dx,
                                  n0[1] + ((a + 0.5) / kSub - 0.5) * dy, 1.0);
          const Eigen::Vector3d q = hi * n;
          sum += q.z() > 0.0 ? shade(target_, im, q.x() / q.z(), q.y() / q.z()) : im.background;
        }
      img(v, u) = static_cast<float>(sum / (kSub * kSub));
    }
  return sim::stereo::expose_8bit(img, im.blur_sigma, im.noise_sigma, rng);
}

}  // namespace dentmark::sim::calibration
