// Stereo calibration on rendered views of known truth (stereo_renderer.h): the
// recovered K1 K2 R T against the K R T the images were rendered with.
//
// Tolerances come from the noise: each camera is also calibrated alone on the same
// corners with cv::calibrateCamera, whose standard deviations (from the residuals and
// the Jacobian) give σ for fx fy cx cy and for every view's pose. R is the mean of the
// per-view R_R R_Lᵀ, so σ_R ≈ sqrt(mean(σ²_rL + σ²_rR) / N) per axis; T = t_R − R t_L
// adds |t_L|·σ_R. Bounds are 5σ (√3 more for 3D norms).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>

#include "../support/temp_dir.h"
#include "dentmark/firmware/calibrate/stereo_from_images.h"
#include "stereo_renderer.h"

namespace dentmark::calibrate {
namespace {

using test::RenderSettings;
using test::Texture;

cv::Matx33d rot(double rx, double ry, double rz) {
  cv::Matx33d r;
  cv::Rodrigues(cv::Vec3d(rx, ry, rz), r);
  return r;
}

struct Truth {
  cv::Matx33d K1{820, 0, 322.5, 0, 820, 238.5, 0, 0, 1};
  cv::Matx33d K2{815, 0, 317.0, 0, 813, 243.0, 0, 0, 1};
  cv::Matx33d R = rot(0.01, -0.04, 0.006);  // p_camR = R p_camL + T
  cv::Vec3d T{-0.12, 0.003, -0.002};
};

struct Pose {
  double tilt_x, tilt_y, roll, x, y, z;
};

// Board poses in camL: tilted up to ±0.45 rad, between the cameras, 0.5–0.8 m away.
const std::vector<Pose> kPoses = {
    {0, 0, 0, 0.06, 0, 0.55},
    {0.4, 0, 0, 0.06, 0, 0.6},
    {-0.4, 0, 0, 0.06, 0, 0.6},
    {0, 0.45, 0, 0.06, 0, 0.6},
    {0, -0.45, 0, 0.06, 0, 0.6},
    {0.3, 0.3, 0.2, 0.06, 0.01, 0.6},
    {-0.3, 0.3, -0.2, 0.05, -0.01, 0.6},
    {0.3, -0.3, 0.1, 0.07, 0.02, 0.6},
    {-0.3, -0.3, -0.1, 0.06, 0, 0.6},
    {0, 0, 0.5, 0.04, 0.02, 0.55},
    {0.2, 0, 0, 0.09, -0.04, 0.7},
    {0, 0.2, -0.4, 0.03, 0.04, 0.6},
    {0.15, -0.25, 0.3, 0.07, 0.02, 0.75},
    {-0.2, 0.1, 0.05, 0.06, 0.03, 0.8},
};

bool inside(const cv::Matx33d& K, const cv::Matx33d& R, const cv::Vec3d& t,
            const std::vector<cv::Point3f>& pts, cv::Size size, double margin) {
  for (const auto& p : pts) {
    const cv::Vec3d q = R * cv::Vec3d(p.x, p.y, p.z) + t;
    if (q[2] <= 0) return false;
    const cv::Vec3d u = K * q;
    const double x = u[0] / u[2], y = u[1] / u[2];
    if (x < margin || y < margin || x > size.width - 1 - margin || y > size.height - 1 - margin) return false;
  }
  return true;
}

struct Scene {
  Truth truth;
  std::vector<cv::Matx33d> R_camL_board;
  std::vector<cv::Vec3d> t_camL_board;
};

// Renders every pose (moved back until the whole target, with a margin, is in both
// images) as left<NN>.png / right<NN>.png.
Scene render_scene(const std::filesystem::path& dir, const Texture& tex,
                   const std::vector<cv::Point3f>& outline, cv::Point3f centre, std::uint64_t seed) {
  Scene s;
  RenderSettings rs;
  cv::RNG rng(seed);
  int n = 1;
  for (const Pose& p : kPoses) {
    const cv::Matx33d R = rot(0, 0, p.roll) * rot(0, p.tilt_y, 0) * rot(p.tilt_x, 0, 0);
    double z = p.z;
    cv::Vec3d t;
    for (;; z += 0.02) {
      t = cv::Vec3d(p.x, p.y, z) - R * cv::Vec3d(centre.x, centre.y, centre.z);
      if (inside(s.truth.K1, R, t, outline, rs.size, 20) &&
          inside(s.truth.K2, s.truth.R * R, s.truth.R * t + s.truth.T, outline, rs.size, 20))
        break;
      if (z > 2.0) ADD_FAILURE() << "pose " << n << " never fits in both images";
    }
    s.R_camL_board.push_back(R);
    s.t_camL_board.push_back(t);
    char name[32];
    std::snprintf(name, sizeof name, "%02d.png", n++);
    cv::imwrite((dir / (std::string("left") + name)).string(),
                test::render_view(tex, s.truth.K1, R, t, rs, rng));
    cv::imwrite((dir / (std::string("right") + name)).string(),
                test::render_view(tex, s.truth.K2, s.truth.R * R, s.truth.R * t + s.truth.T, rs, rng));
  }
  return s;
}

struct Sigmas {
  double fx1, fy1, cx1, cy1, fx2, fy2, cx2, cy2;
  double rot_axis, trans_axis;
};

// Covariance-based σ from each camera calibrated alone on the same corners.
Sigmas sigmas_from_noise(const std::filesystem::path& dir, const TargetSpec& target) {
  std::vector<std::vector<cv::Point3f>> obj;
  std::vector<std::vector<cv::Point2f>> img[2];
  cv::Size size;
  for (const ImagePair& p : find_image_pairs(dir)) {
    const cv::Mat l = cv::imread(p.left.string(), cv::IMREAD_GRAYSCALE);
    const cv::Mat r = cv::imread(p.right.string(), cv::IMREAD_GRAYSCALE);
    size = l.size();
    const StereoView v = stereo_view(target, p.name, detect_target(target, l), detect_target(target, r));
    if (v.object.size() < 6) continue;
    obj.push_back(v.object);
    img[0].push_back(v.left);
    img[1].push_back(v.right);
  }
  cv::Mat sd_in[2], sd_ex[2];
  std::vector<cv::Mat> rv, tv;
  for (int c = 0; c < 2; ++c) {
    cv::Mat k, d, per_view;
    cv::calibrateCamera(obj, img[c], size, k, d, rv, tv, sd_in[c], sd_ex[c], per_view);
  }
  Sigmas s{};
  s.fx1 = sd_in[0].at<double>(0), s.fy1 = sd_in[0].at<double>(1), s.cx1 = sd_in[0].at<double>(2),
  s.cy1 = sd_in[0].at<double>(3);
  s.fx2 = sd_in[1].at<double>(0), s.fy2 = sd_in[1].at<double>(1), s.cx2 = sd_in[1].at<double>(2),
  s.cy2 = sd_in[1].at<double>(3);
  const int n = static_cast<int>(obj.size());
  double sr = 0, st = 0;
  for (int i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) {
      const double r2 =
          std::pow(sd_ex[0].at<double>(6 * i + a), 2) + std::pow(sd_ex[1].at<double>(6 * i + a), 2);
      const double t2 =
          std::pow(sd_ex[0].at<double>(6 * i + 3 + a), 2) + std::pow(sd_ex[1].at<double>(6 * i + 3 + a), 2);
      sr += r2 / 3.0;
      st += t2 / 3.0 + 0.7 * 0.7 * r2 / 3.0;  // |t_L| ≤ 0.8 m
    }
  s.rot_axis = std::sqrt(sr / n / n);
  s.trans_axis = std::sqrt(st / n / n);
  return s;
}

void expect_recovers_truth(const StereoCalibrationRun& run, const Truth& truth, const Sigmas& sd) {
  const track::StereoCalibration& c = run.fit.calibration;
  std::printf("rendered: %d of %zu views, RMS %.4f px, epipolar %.4f px, hold-out %.4f px, square %.6f m\n",
              run.fit.views_used, run.views.size(), run.fit.rms_px, run.fit.epipolar_rectified_px,
              run.fit.holdout_rms_px, run.fit.square_measured_m);
  std::printf("  fx1 %.3f (truth %.1f, 5σ %.3f)  cx1 %.3f (%.1f, %.3f)  fx2 %.3f (%.1f, %.3f)\n",
              c.left.K(0, 0), truth.K1(0, 0), 5 * sd.fx1, c.left.K(0, 2), truth.K1(0, 2), 5 * sd.cx1,
              c.right.K(0, 0), truth.K2(0, 0), 5 * sd.fx2);
  EXPECT_EQ(run.fit.views_used, static_cast<int>(run.views.size()));
  EXPECT_NEAR(c.left.K(0, 0), truth.K1(0, 0), 5 * sd.fx1);
  EXPECT_NEAR(c.left.K(1, 1), truth.K1(1, 1), 5 * sd.fy1);
  EXPECT_NEAR(c.left.K(0, 2), truth.K1(0, 2), 5 * sd.cx1);
  EXPECT_NEAR(c.left.K(1, 2), truth.K1(1, 2), 5 * sd.cy1);
  EXPECT_NEAR(c.right.K(0, 0), truth.K2(0, 0), 5 * sd.fx2);
  EXPECT_NEAR(c.right.K(1, 1), truth.K2(1, 1), 5 * sd.fy2);
  EXPECT_NEAR(c.right.K(0, 2), truth.K2(0, 2), 5 * sd.cx2);
  EXPECT_NEAR(c.right.K(1, 2), truth.K2(1, 2), 5 * sd.cy2);
  Eigen::Matrix3d r_true;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r_true(i, j) = truth.R(i, j);
  const double angle = Eigen::AngleAxisd(c.T_camR_camL.linear().transpose() * r_true).angle();
  const Eigen::Vector3d t_true(truth.T[0], truth.T[1], truth.T[2]);
  const double dt = (c.T_camR_camL.translation() - t_true).norm();
  std::printf("  R error %.2e rad (5σ %.2e), T error %.2e m (5σ %.2e)\n", angle,
              5 * std::sqrt(3.0) * sd.rot_axis, dt, 5 * std::sqrt(3.0) * sd.trans_axis);
  EXPECT_LT(angle, 5 * std::sqrt(3.0) * sd.rot_axis);
  EXPECT_LT(dt, 5 * std::sqrt(3.0) * sd.trans_axis);
  // The noise is what the residuals measure: 2 grey levels on a 175-level edge, blurred.
  EXPECT_LT(run.fit.rms_px, 0.1);
  EXPECT_LT(run.fit.holdout_rms_px, 1.5 * run.fit.rms_px);
  EXPECT_LT(run.fit.epipolar_rectified_px, run.fit.rms_px);
}

TEST(RenderedStereo, ChessboardRecoversKnownKRT) {
  ::dentmark::test::TempDir dir("calib-render");
  const TargetSpec target = parse_target("chessboard:9x6", 0.025, 0.0, "");
  const Texture tex = test::chessboard_texture(9, 6, 0.025);
  // The board's outer edge (one square outside the inner corners) must stay in view.
  const std::vector<cv::Point3f> outline = {
      {-0.05f, -0.05f, 0}, {0.25f, -0.05f, 0}, {0.25f, 0.175f, 0}, {-0.05f, 0.175f, 0}};
  const Scene scene = render_scene(dir.path(), tex, outline, {0.1f, 0.0625f, 0}, 1234);
  const StereoCalibrationRun run = calibrate_stereo_images(dir.path(), target);
  expect_recovers_truth(run, scene.truth, sigmas_from_noise(dir.path(), target));
  EXPECT_NEAR(run.fit.square_measured_m / 0.025, 1.0, 0.002);
}

TEST(RenderedStereo, CharucoRecoversKnownKRT) {
  ::dentmark::test::TempDir dir("calib-render-charuco");
  const TargetSpec target = parse_target("charuco:8x6", 0.03, 0.022, "DICT_5X5_100");
  const int px = 64;
  const cv::Ptr<cv::aruco::CharucoBoard> board = cv::aruco::CharucoBoard::create(
      8, 6, 0.03f, 0.022f, cv::aruco::getPredefinedDictionary(cv::aruco::DICT_5X5_100));
  Texture tex;
  board->draw(cv::Size(10 * px, 8 * px), tex.image, px, 1);
  // 40 / 215 grey like the chessboard, so both see the same contrast.
  tex.image.convertTo(tex.image, CV_8U, 175.0 / 255.0, 40.0);
  const double scale = px / 0.03;
  tex.texture_from_board = cv::Matx33d(scale, 0, px - 0.5, 0, scale, px - 0.5, 0, 0, 1);
  const std::vector<cv::Point3f> outline = {
      {-0.02f, -0.02f, 0}, {0.26f, -0.02f, 0}, {0.26f, 0.2f, 0}, {-0.02f, 0.2f, 0}};
  const Scene scene = render_scene(dir.path(), tex, outline, {0.12f, 0.09f, 0}, 99);
  const StereoCalibrationRun run = calibrate_stereo_images(dir.path(), target);
  expect_recovers_truth(run, scene.truth, sigmas_from_noise(dir.path(), target));
  EXPECT_NEAR(run.fit.square_measured_m / 0.03, 1.0, 0.002);
}

// ChArUco corner ids index OpenCV's own board layout.
TEST(RenderedStereo, CharucoCornerIdsMatchOpenCvBoard) {
  const TargetSpec target = parse_target("charuco:8x6", 0.03, 0.022, "DICT_5X5_100");
  const cv::Ptr<cv::aruco::CharucoBoard> board = cv::aruco::CharucoBoard::create(
      8, 6, 0.03f, 0.022f, cv::aruco::getPredefinedDictionary(cv::aruco::DICT_5X5_100));
  ASSERT_EQ(static_cast<int>(board->chessboardCorners.size()), target.corner_count());
  for (int id = 0; id < target.corner_count(); ++id) {
    const cv::Point3f d = target.corner(id) - board->chessboardCorners[static_cast<std::size_t>(id)];
    EXPECT_LT(cv::norm(d), 1e-6) << id;
  }
}

}  // namespace
}  // namespace dentmark::calibrate
