// The live robot calibration's pipeline (plan → move → grab → detect → triangulate →
// fit → verify) on samples from a second, independent image generator: the chessboard
// drawn by OpenCV (cv::rectangle) on a flat image and warped into each camera by the
// homography of its outer corners projected with cv::projectPoints, with a noise model
// of its own (optical blur, shot noise growing with brightness, a vignetting gain).
// It shares no code with the twin's renderer (sim/calibration), nor its rig or truth.
// The robot is an exact in-memory one (no Modbus: live_robot.sh covers the link).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"
#include "dentmark/firmware/calibrate/robot_live.h"

namespace dentmark::calibrate {
namespace {

// An exact robot: a move ends at once, where it was sent.
class ExactRobot final : public hal::Robot {
 public:
  explicit ExactRobot(clock::Clock& clock, Transform home) : clock_(clock), pose_(home) {}
  void connect() override { connected_ = true; }
  void disconnect() override { connected_ = false; }
  bool connected() const override { return connected_; }
  std::uint16_t move_to(const Transform& T, double) override {
    pose_ = T;
    clock_.sleep_until(clock_.now() + 2.0);  // a move takes time
    return ++seq_;
  }
  std::uint16_t spray(double) override { return ++seq_; }
  std::uint16_t abort() override { return ++seq_; }
  std::uint16_t reset() override { return ++seq_; }
  void heartbeat() override {}
  hal::RobotStatus status() override {
    hal::RobotStatus s;
    s.sequence = seq_;
    s.T_base_tool = pose_;
    s.robot_time = clock_.now();
    return s;
  }

 private:
  clock::Clock& clock_;
  Transform pose_;
  std::uint16_t seq_ = 0;
  bool connected_ = false;
};

struct WarpRig {
  cv::Size size{1280, 960};
  cv::Matx33d K[2] = {{1650, 0, 645, 0, 1650, 478, 0, 0, 1}, {1655, 0, 630, 0, 1655, 485, 0, 0, 1}};
  Transform T_camR_camL =
      make_transform_rotvec(Eigen::Vector3d(0, -0.09, 0.002), Eigen::Vector3d(-0.42, 0.004, 0.03));
  Transform T_base_camL =
      make_transform_rotvec(Eigen::Vector3d(0.05, -0.08, 0.03), Eigen::Vector3d(0.2, -0.15, -2.1));
  Transform T_tool_target =
      make_transform_rotvec(Eigen::Vector3d(0, 0, 0.02), Eigen::Vector3d(-0.1, -0.08, 0.015));
  int cols = 9, rows = 6;  // inner corners; COLS + ROWS odd
  double square = 0.025;
};

// The flat board at px pixels per square: square (a, b), a = −1…cols − 1, black when a + b is
// even; one white square of border.
cv::Mat board_image(const WarpRig& w, double px) {
  const int W = static_cast<int>((w.cols + 3) * px), H = static_cast<int>((w.rows + 3) * px);
  cv::Mat img(H, W, CV_8U, cv::Scalar(220));
  for (int b = -1; b < w.rows; ++b)
    for (int a = -1; a < w.cols; ++a)
      if (((a + b) & 1) == 0)
        cv::rectangle(img,
                      cv::Rect(static_cast<int>((a + 2) * px), static_cast<int>((b + 2) * px),
                               static_cast<int>(px), static_cast<int>(px)),
                      cv::Scalar(30), cv::FILLED);
  return img;
}

cv::Mat warp_view(const WarpRig& w, int eye, const Transform& T_camL_target, cv::RNG& rng) {
  constexpr double kPx = 40.0;
  static const cv::Mat flat = board_image(w, kPx);
  const Transform T = (eye == 0 ? Transform::Identity() : w.T_camR_camL) * T_camL_target;
  // Board image corners ↔ target-plane points (x = (u / px − 2)·square).
  const double s = w.square;
  // The flat image's outer edges (OpenCV puts pixel centres on integers).
  const float W = static_cast<float>(flat.cols) - 0.5f, H = static_cast<float>(flat.rows) - 0.5f;
  const std::vector<cv::Point2f> src{{-0.5f, -0.5f}, {W, -0.5f}, {W, H}, {-0.5f, H}};
  std::vector<cv::Point3d> obj;
  for (const auto& p : src) {
    const Eigen::Vector3d q =
        T * Eigen::Vector3d(((p.x + 0.5) / kPx - 2) * s, ((p.y + 0.5) / kPx - 2) * s, 0.0);
    obj.emplace_back(q.x(), q.y(), q.z());
  }
  std::vector<cv::Point2d> img;
  cv::projectPoints(obj, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), w.K[eye], cv::noArray(), img);
  const std::vector<cv::Point2f> dst(img.begin(), img.end());
  cv::Mat out(w.size, CV_8U, cv::Scalar(70));
  cv::warpPerspective(flat, out, cv::getPerspectiveTransform(src, dst), w.size, cv::INTER_LINEAR,
                      cv::BORDER_TRANSPARENT);
  cv::Mat f;
  out.convertTo(f, CV_32F);
  cv::GaussianBlur(f, f, cv::Size(0, 0), 1.0);
  // Vignetting: gain falling to 0.85 at the corners; shot noise σ = sqrt(I / 9).
  for (int y = 0; y < f.rows; ++y)
    for (int x = 0; x < f.cols; ++x) {
      const double r2 = (std::pow(x - 0.5 * f.cols, 2) + std::pow(y - 0.5 * f.rows, 2)) /
                        (0.25 * (f.cols * f.cols + f.rows * f.rows));
      float& v = f.at<float>(y, x);
      v = static_cast<float>(v * (1.0 - 0.15 * r2));
      v += static_cast<float>(rng.gaussian(std::sqrt(std::max(1.0f, v) / 9.0)));
    }
  f.convertTo(out, CV_8U);
  return out;
}

class WarpCamera final : public hal::Camera {
 public:
  WarpCamera(const WarpRig& w, int eye, ExactRobot& robot, clock::Clock& clock)
      : w_(w), eye_(eye), robot_(robot), clock_(clock), name_(eye == 0 ? "warp:L" : "warp:R") {}
  void start() override {}
  void stop() override {}
  std::optional<hal::Frame> grab(double) override {
    clock_.sleep_until(clock_.now() + 0.1);
    const Transform T_camL_target = w_.T_base_camL.inverse() * robot_.status().T_base_tool * w_.T_tool_target;
    hal::Frame f{warp_view(w_, eye_, T_camL_target, rng_), clock_.now(), seq_++};
    if (const char* dir = std::getenv("DENTMARK_WARP_DUMP"))
      cv::imwrite(std::string(dir) + "/" + name_.substr(5) + std::to_string(f.sequence) + ".png", f.image);
    return f;
  }
  cv::Size size() const override { return w_.size; }
  const std::string& name() const override { return name_; }

 private:
  const WarpRig& w_;
  int eye_;
  ExactRobot& robot_;
  clock::Clock& clock_;
  std::string name_;
  cv::RNG rng_{static_cast<std::uint64_t>(11 + eye_)};
  std::uint64_t seq_ = 0;
};

track::StereoCalibration stereo_of(const WarpRig& w) {
  track::StereoCalibration s;
  s.size = w.size;
  s.left.K = w.K[0];
  s.right.K = w.K[1];
  s.T_camR_camL = w.T_camR_camL;
  return s;
}

ToolTarget target_of(const WarpRig& w) {
  ToolTarget t;
  t.spec =
      parse_target("chessboard:" + std::to_string(w.cols) + "x" + std::to_string(w.rows), w.square, 0, "");
  t.T_tool_target = w.T_tool_target;
  return t;
}

// Point transfer RMS against the truth on held-out poses.
double truth_transfer_rms(const WarpRig& w, const Transform& est, const std::vector<Transform>& poses) {
  double sum = 0.0;
  std::size_t n = 0;
  for (const Transform& T_base_tool : poses)
    for (const Eigen::Vector3d& p : target_of(w).points_tool()) {
      const Eigen::Vector3d p_camL = w.T_base_camL.inverse() * T_base_tool * p;
      sum += (est * p_camL - T_base_tool * p).squaredNorm(), ++n;
    }
  return std::sqrt(sum / static_cast<double>(n));
}

TEST(RobotLive, WarpedTargetCalibratesWithinHalfAMillimetre) {
  const WarpRig w;
  clock::SimClock clock;  // manual: sleeping moves time
  // The tool turned half a revolution about x so that the board faces the cameras.
  const Transform home =
      make_transform_rotvec(Eigen::Vector3d(3.14159265, 0.0, 0.0), Eigen::Vector3d(0.0, 0.1, 0.3));
  {
    const Transform T_camL_target = w.T_base_camL.inverse() * home * w.T_tool_target;
    ASSERT_LT(T_camL_target.linear().col(2).z(), -0.9) << "the test's start pose must face the cameras";
  }
  ExactRobot robot(clock, home);
  WarpCamera left(w, 0, robot, clock), right(w, 1, robot, clock);
  const track::StereoCalibration stereo = stereo_of(w);
  const ToolTarget target = target_of(w);
  TargetRig rig(robot, left, right, clock, stereo, target);
  PosePlanOptions plan;
  plan.poses = 15;
  plan.workspace_min = Eigen::Vector3d(-0.5, -0.5, 0.0);
  plan.workspace_max = Eigen::Vector3d(0.6, 0.6, 0.8);
  const LiveCalibration live =
      calibrate_robot_live(rig, target, stereo, plan, [](std::size_t i, std::size_t n, const PoseRecord& r) {
        std::printf("pose %zu/%zu: %s\n", i + 1, n, r.used ? "measured" : ("skipped: " + r.why).c_str());
        std::fflush(stdout);
      });
  EXPECT_EQ(live.planned.size(), 15u);
  EXPECT_GE(live.acquisition.samples.samples.size(), 14u);
  PosePlanOptions held = plan;
  held.poses = 40;
  held.halton_offset = 30000;
  held.min_separation = 0.05;
  const auto check = plan_calibration_poses(target, stereo, w.T_base_camL, home, held);
  const double rms = truth_transfer_rms(w, live.fit.T_base_camL, check);
  std::printf(
      "warped target, %zu of %zu poses, %dx%d px: fit RMS %.3f mm, hold-out %.3f mm, truth transfer on "
      "%zu held-out poses %.3f mm, hand-eye %.2f mm\n",
      live.acquisition.samples.samples.size(), live.planned.size(), w.size.width, w.size.height,
      live.fit.rms_m * 1e3, live.fit.holdout_rms_m * 1e3, check.size(), rms * 1e3,
      live.fit.handeye_translation_diff_m * 1e3);
  EXPECT_LT(rms, 0.0005);
  // The hold-out figure is per point, so it carries each corner's triangulation noise
  // (this generator's shot noise and aliased edges: about 1.5 mm at 2.3 m); the truth
  // figure above is what the calibration itself is worth.
  EXPECT_LT(live.fit.holdout_rms_m, 0.0025);
  EXPECT_LT(live.fit.handeye_translation_diff_m, 0.010);

  // Verify (tolerance 4 mm, above this generator's point noise): the fitted transform
  // holds; one shifted by 10 mm does not.
  PosePlanOptions vplan = plan;
  vplan.poses = 3;
  vplan.halton_offset = 5000;
  const LiveVerify good = verify_robot_live(rig, target, stereo, live.fit.T_base_camL, vplan, 0.004);
  EXPECT_TRUE(good.result.holds) << good.result.reason;
  EXPECT_EQ(good.result.poses_measured, 3);
  const Transform shifted =
      make_transform_rotvec(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.010, 0, 0)) * live.fit.T_base_camL;
  const LiveVerify bad = verify_robot_live(rig, target, stereo, shifted, vplan, 0.004);
  EXPECT_FALSE(bad.result.holds);
  EXPECT_GT(bad.result.rms_m, 0.008);
  EXPECT_NE(bad.result.reason.find("point transfer RMS"), std::string::npos) << bad.result.reason;
}

TEST(RobotLive, TargetNotSeenAtTheStartIsAClearError) {
  const WarpRig w;
  clock::SimClock clock;
  // Facing the cameras but 2.5 m to the side, out of both views.
  ExactRobot robot(clock,
                   make_transform_rotvec(Eigen::Vector3d(3.14159265, 0, 0), Eigen::Vector3d(2.5, 0.1, 0.3)));
  WarpCamera left(w, 0, robot, clock), right(w, 1, robot, clock);
  const track::StereoCalibration stereo = stereo_of(w);
  TargetRig rig(robot, left, right, clock, stereo, target_of(w));
  PosePlanOptions plan;
  plan.workspace_min = Eigen::Vector3d(-0.5, -0.5, 0.0);
  plan.workspace_max = Eigen::Vector3d(0.6, 0.6, 0.8);
  try {
    calibrate_robot_live(rig, target_of(w), stereo, plan);
    FAIL() << "no error";
  } catch (const CalibrateError& e) {
    EXPECT_NE(std::string(e.what()).find("jog the robot"), std::string::npos) << e.what();
  }
}

TEST(RobotLive, AmbiguousChessboardIsRefused) {
  EXPECT_THROW(require_oriented_chessboard(parse_target("chessboard:7x5", 0.03, 0, "")), CalibrateError);
  EXPECT_NO_THROW(require_oriented_chessboard(parse_target("chessboard:7x6", 0.03, 0, "")));
}

}  // namespace
}  // namespace dentmark::calibrate
