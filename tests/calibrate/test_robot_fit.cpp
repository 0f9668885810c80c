// Robot-to-stereo calibration from synthetic samples of known truth: a target on the
// tool at 20 robot poses, its points seen by the stereo pair with triangulation noise
// (σ 0.1 mm across, 0.3 mm in depth, in camL) and the robot's 0.05 mm repeatability.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <opencv2/core.hpp>
#include <random>

#include "../support/temp_dir.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"
#include "dentmark/firmware/calibrate/robot_calibration_file.h"
#include "dentmark/firmware/station/station_calibration.h"

namespace dentmark::calibrate {
namespace {

constexpr double kSigmaXY = 0.1e-3, kSigmaZ = 0.3e-3, kRobot = 0.05e-3;

struct Synthetic {
  Transform T_base_camL_true;
  RobotSamples samples;
};

Synthetic make_samples(int poses, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  Synthetic s;
  // Camera 2.8 m from the work area, looking back at it.
  s.T_base_camL_true =
      make_transform_rotvec(Eigen::Vector3d(0.4, -1.9, 0.6), Eigen::Vector3d(2.9, -0.5, 1.7));
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 3; ++j)
      s.samples.target_points_tool.emplace_back(0.05 + 0.04 * i, -0.04 + 0.04 * j, 0.12);
  for (int k = 0; k < poses; ++k) {
    RobotSample r;
    const Eigen::Vector3d rv(0.5 * u(rng), 0.5 * u(rng), 0.8 * u(rng));
    const Eigen::Vector3d t(0.65 + 0.25 * u(rng), 0.3 * u(rng), 0.55 + 0.25 * u(rng));
    const Transform T_base_tool_true = make_transform_rotvec(rv, t);
    // The robot reports its pose with its repeatability error.
    r.T_base_tool = T_base_tool_true;
    r.T_base_tool.translation() += kRobot * Eigen::Vector3d(g(rng), g(rng), g(rng));
    for (const auto& p : s.samples.target_points_tool) {
      const Eigen::Vector3d c = s.T_base_camL_true.inverse() * (T_base_tool_true * p);
      r.points_camL.push_back(c + Eigen::Vector3d(kSigmaXY * g(rng), kSigmaXY * g(rng), kSigmaZ * g(rng)));
    }
    s.samples.samples.push_back(std::move(r));
  }
  return s;
}

TEST(RobotFit, RecoversTBaseCamLFromSyntheticSamples) {
  const Synthetic s = make_samples(20, 7);
  const RobotFit f = fit_robot(s.samples);
  // Tolerances from the noise: M points with σ (the largest axis, plus the robot's) give
  // a rotation error ≈ σ / (√M · r) (r: the points' RMS distance from their centroid)
  // and a translation error at camL ≈ σ/√M + d · that angle (d: camL to the centroid).
  const double sigma = std::hypot(kSigmaZ, kRobot);
  std::vector<Eigen::Vector3d> pts;
  for (const auto& r : s.samples.samples)
    for (const auto& p : s.samples.target_points_tool) pts.push_back(r.T_base_tool * p);
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& p : pts) c += p;
  c /= static_cast<double>(pts.size());
  double r2 = 0.0;
  for (const auto& p : pts) r2 += (p - c).squaredNorm();
  const double m = static_cast<double>(pts.size()), r = std::sqrt(r2 / m);
  const double d = (s.T_base_camL_true.translation() - c).norm();
  const double angle_sd = sigma / (std::sqrt(m) * r), trans_sd = sigma / std::sqrt(m) + d * angle_sd;
  const double angle = rotation_angle_between(f.T_base_camL, s.T_base_camL_true);
  const double dt = (f.T_base_camL.translation() - s.T_base_camL_true.translation()).norm();
  std::printf(
      "robot fit: 20 poses x 12 points: RMS %.3f mm, hold-out %.3f mm (worst pose %.3f mm); error %.3f mm "
      "(5σ %.3f), %.3f mrad (5σ %.3f); hand-eye %.3f mm / %.3f mrad apart\n",
      f.rms_m * 1e3, f.holdout_rms_m * 1e3, f.holdout_max_pose_m * 1e3, dt * 1e3,
      5 * std::sqrt(3.0) * trans_sd * 1e3, angle * 1e3, 5 * std::sqrt(3.0) * angle_sd * 1e3,
      f.handeye_translation_diff_m * 1e3, f.handeye_rotation_diff_rad * 1e3);
  EXPECT_LT(angle, 5 * std::sqrt(3.0) * angle_sd);
  EXPECT_LT(dt, 5 * std::sqrt(3.0) * trans_sd);
  // Residuals are the noise: 3D σ = √(2 σ_xy² + σ_z² + 3 σ_robot²).
  const double noise3d = std::sqrt(2 * kSigmaXY * kSigmaXY + kSigmaZ * kSigmaZ + 3 * kRobot * kRobot);
  EXPECT_NEAR(f.rms_m / noise3d, 1.0, 0.2);
  EXPECT_NEAR(f.holdout_rms_m / noise3d, 1.0, 0.25);
  EXPECT_LT(f.holdout_rms_m, 0.5e-3);  // the station's target on held-out poses
  // OpenCV's robot-world/hand-eye solution of the same chain agrees with the truth and
  // sees the target's mount as drawn (target frame = tool frame), within its own noise:
  // each sample's target pose from 12 points 0.12 m across, σ 0.3 mm, is good to a few
  // mrad, which its closed form carries 2.8 m to camL.
  const double he_dt = (f.T_base_camL_handeye.translation() - s.T_base_camL_true.translation()).norm();
  std::printf("hand-eye against the truth: %.3f mm, %.3f mrad\n", he_dt * 1e3,
              rotation_angle_between(f.T_base_camL_handeye, s.T_base_camL_true) * 1e3);
  EXPECT_LT(he_dt, 5e-3);
  EXPECT_LT(rotation_angle_between(f.T_base_camL_handeye, s.T_base_camL_true), 3e-3);
  EXPECT_LT(f.handeye_translation_diff_m, 5e-3);
  EXPECT_LT(f.T_target_tool_handeye.translation().norm(), 5e-3);
  EXPECT_LT(Eigen::AngleAxisd(f.T_target_tool_handeye.linear()).angle(), 5e-3);
}

// One pose recorded against the wrong robot pose (the robot moved on before the
// cameras fired) stands out in the hold-out figures.
TEST(RobotFit, WrongPoseStandsOutInHoldOut) {
  Synthetic s = make_samples(18, 11);
  s.samples.samples[5].T_base_tool.translation() += Eigen::Vector3d(0.004, -0.003, 0.0);
  const RobotFit f = fit_robot(s.samples);
  const auto worst = std::max_element(f.holdout_pose_rms_m.begin(), f.holdout_pose_rms_m.end());
  EXPECT_EQ(worst - f.holdout_pose_rms_m.begin(), 5);
  EXPECT_GT(*worst, 4e-3);
}

TEST(RobotFit, RefusesTooFewOrMismatchedSamples) {
  Synthetic s = make_samples(2, 3);
  EXPECT_THROW(fit_robot(s.samples), CalibrateError);
  s = make_samples(5, 3);
  s.samples.samples[2].points_camL.pop_back();
  try {
    fit_robot(s.samples);
    FAIL();
  } catch (const CalibrateError& e) {
    EXPECT_STREQ(e.what(), "samples[2].points_camL: 11 points, target_points_tool has 12");
  }
}

class RobotFiles : public ::testing::Test {
 protected:
  std::filesystem::path write_samples(const RobotSamples& s, const std::string& name) {
    const auto p = dir_.path() / name;
    cv::FileStorage fs(p.string(), cv::FileStorage::WRITE);
    auto mat = [](const std::vector<Eigen::Vector3d>& v) {
      cv::Mat m(static_cast<int>(v.size()), 3, CV_64F);
      for (int i = 0; i < m.rows; ++i)
        for (int k = 0; k < 3; ++k) m.at<double>(i, k) = v[static_cast<std::size_t>(i)](k);
      return m;
    };
    fs << "target_points_tool" << mat(s.target_points_tool) << "samples"
       << "[";
    for (const auto& r : s.samples) {
      cv::Mat t(4, 4, CV_64F);
      for (int i = 0; i < 4; ++i)
        for (int k = 0; k < 4; ++k) t.at<double>(i, k) = r.T_base_tool.matrix()(i, k);
      fs << "{"
         << "T_base_tool" << t << "points_camL" << mat(r.points_camL) << "}";
    }
    fs << "]";
    return p;
  }
  ::dentmark::test::TempDir dir_{"calib-robot"};
};

TEST_F(RobotFiles, SamplesRoundTripAndResultLoads) {
  const Synthetic s = make_samples(16, 5);
  const RobotSamples back = read_robot_samples(write_samples(s.samples, "samples.yaml"));
  ASSERT_EQ(back.samples.size(), 16u);
  EXPECT_TRUE(back.samples[3].T_base_tool.isApprox(s.samples.samples[3].T_base_tool, 1e-12));
  RobotCalibrationRun run;
  run.fit = fit_robot(back);
  run.poses = 16, run.points_per_pose = 12;
  const auto out = dir_.path() / "robot.yaml";
  write_robot_calibration(out.string(), run);
  EXPECT_TRUE(load_robot_calibration(out).isApprox(run.fit.T_base_camL, 1e-12));
  // The daemon reads it too (its calibration folder's robot.yaml).
  EXPECT_TRUE(station::load_transform(out, "T_base_camL").isApprox(run.fit.T_base_camL, 1e-12));
  // Over the hold-out limit: refused, naming the field.
  run.fit.holdout_rms_m = 1.5e-3;
  write_robot_calibration(out.string(), run);
  try {
    load_robot_calibration(out);
    FAIL();
  } catch (const CalibrateError& e) {
    EXPECT_EQ(std::string(e.what()),
              out.string() + ": field holdout_rms_m is 1.500 mm, over the limit of 1.000 mm: recalibrate");
  }
}

TEST_F(RobotFiles, RefusesNonRigidPose) {
  Synthetic s = make_samples(4, 9);
  s.samples.samples[1].T_base_tool.linear() *= 1.01;
  const auto p = write_samples(s.samples, "bad.yaml");
  try {
    read_robot_samples(p);
    FAIL();
  } catch (const CalibrateError& e) {
    EXPECT_EQ(std::string(e.what()), p.string() +
                                         ": field samples[1].T_base_tool is not rigid (rotation not "
                                         "orthonormal: |R^T R - I| > 1e-3)");
  }
}

}  // namespace
}  // namespace dentmark::calibrate

namespace dentmark::calibrate {
namespace {

// Writes the samples the command test (calibrate_cli_robot, tests/calibrate/CMakeLists.txt)
// runs `calibrate robot --from-file` on: to $DENTMARK_ROBOT_SAMPLES_OUT when set.
TEST_F(RobotFiles, SamplesForTheCommandTest) {
  const Synthetic s = make_samples(20, 7);
  const char* out = std::getenv("DENTMARK_ROBOT_SAMPLES_OUT");
  const std::filesystem::path p = write_samples(s.samples, "command_samples.yaml");
  ASSERT_EQ(read_robot_samples(p).samples.size(), 20u);
  if (out) std::filesystem::copy_file(p, out, std::filesystem::copy_options::overwrite_existing);
}

}  // namespace
}  // namespace dentmark::calibrate
