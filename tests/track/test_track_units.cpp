// Unit tests of the tracker's parts against closed-form answers.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <opencv2/imgproc.hpp>
#include <random>

#include "dentmark/firmware/track/motion_filter.h"
#include "dentmark/firmware/track/robust_motion.h"
#include "dentmark/firmware/track/sequence.h"
#include "dentmark/firmware/track/stereo_calibration.h"
#include "dentmark/firmware/track/template_align.h"
#include "dentmark/firmware/track/track_error.h"
#include "sequence_fixture.h"

namespace dentmark::track {
namespace {

StereoCalibration rig(double k1 = 0.0) {
  StereoCalibration c;
  c.size = {1280, 1024};
  c.left.K = cv::Matx33d(1740, 0, 636, 0, 1741, 515, 0, 0, 1);
  c.right.K = cv::Matx33d(1745, 0, 644, 0, 1744, 510, 0, 0, 1);
  c.left.D = (cv::Mat_<double>(1, 5) << k1, 0.02, 0.001, -0.0005, 0);
  c.right.D = (cv::Mat_<double>(1, 5) << k1 * 0.9, 0.01, -0.001, 0.0003, 0);
  c.T_camR_camL =
      make_transform_rotvec(Eigen::Vector3d(0.01, 0.09, -0.005), Eigen::Vector3d(-0.49, 0.01, 0.045));
  return c;
}

TEST(Triangulate, RecoversPointsThroughDistortedCameras) {
  const StereoCalibration c = rig(-0.15);
  for (const Eigen::Vector3d& p :
       {Eigen::Vector3d(0.1, -0.2, 2.8), Eigen::Vector3d(0.6, 0.4, 2.5), Eigen::Vector3d(-0.3, 0.3, 3.4)}) {
    const auto l = c.project(Cam::kLeft, {p}), r = c.project(Cam::kRight, {p});
    const Triangulation t = triangulate(c, c.normalize(Cam::kLeft, l)[0], c.normalize(Cam::kRight, r)[0]);
    // float pixels (1e-4 px) bound the error at ~1e-6 m here.
    EXPECT_LT((t.p_camL - p).norm(), 2e-5);
    EXPECT_LT(t.reprojection_px, 1e-3);
  }
}

TEST(RobustMotion, IgnoresFourOfTenFeaturesThatSlidOntoTheArm) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 1e-4);
  const Transform truth =
      make_transform_rotvec(Eigen::Vector3d(0.002, -0.01, 0.004), Eigen::Vector3d(0.05, 0, 0.01));
  std::vector<Eigen::Vector3d> from, to;
  for (int i = 0; i < 10; ++i) {
    from.emplace_back(-0.5 + 0.11 * i, 0.2 * std::sin(i), 2.8 + 0.05 * std::cos(3 * i));
    Eigen::Vector3d q = truth * from.back() + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    if (i % 3 == 0 && i < 10) q += Eigen::Vector3d(0.02, -0.03, 0.05 * (i + 1) / 10.0);  // 0, 3, 6, 9
    to.push_back(q);
  }
  const RobustMotion m = fit_rigid_robust(from, to, {}, {});
  EXPECT_EQ(m.inliers, 6);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(m.inlier[static_cast<std::size_t>(i)], i % 3 != 0) << i;
  EXPECT_LT((m.T_to_from.translation() - truth.translation()).norm(), 1e-3);
  EXPECT_LT(rotation_angle_between(m.T_to_from, truth), 1e-3);
}

TEST(MotionFilter, AveragesNoiseOnASmoothLineAndFollowsAStopAtOnce) {
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 2e-4);
  MotionFilter f(Eigen::Vector3d(0.2, 0, 2.8), {});
  f.reset(0.0);
  double raw_sq = 0.0, filt_sq = 0.0;
  int n = 0;
  double x_true = 0.0;
  double worst_after_stop = 0.0;
  for (int k = 1; k <= 200; ++k) {
    const double t = 0.1 * k;
    const bool moving = t < 10.0;
    if (moving) x_true += 0.014 * 0.1;
    Transform meas = Transform::Identity();
    meas.translation() = Eigen::Vector3d(x_true + noise(rng), noise(rng), noise(rng));
    const Transform out = f.update(t, meas, Eigen::Vector3d::Constant(1e-4), Eigen::Vector3d::Constant(2e-4));
    const double e_raw = std::abs(meas.translation().x() - x_true),
                 e = std::abs(out.translation().x() - x_true);
    if (k > 20 && moving) raw_sq += e_raw * e_raw, filt_sq += e * e, ++n;
    if (!moving && t > 10.25) worst_after_stop = std::max(worst_after_stop, e);
  }
  EXPECT_LT(std::sqrt(filt_sq / n), 0.8 * std::sqrt(raw_sq / n));
  // Two frames after the stop the filter has let go of the old speed.
  EXPECT_LT(worst_after_stop, 1e-3);
}

TEST(TemplateAlign, FindsASubPixelShiftUnderALightingChange) {
  cv::Mat1f scene(200, 200);
  for (int y = 0; y < 200; ++y)
    for (int x = 0; x < 200; ++x) scene(y, x) = (x > 95 && y > 102 ? 170.f : 60.f) + 0.2f * x;
  cv::GaussianBlur(scene, scene, cv::Size(0, 0), 0.8);
  cv::Mat a, b;
  scene.convertTo(a, CV_8U);
  const double dx = 0.37, dy = -0.61;
  cv::Mat shifted;
  cv::warpAffine(scene, shifted, cv::Matx23d(1, 0, dx, 0, 1, dy), scene.size(), cv::INTER_CUBIC);
  shifted = shifted * 1.3 + 5.0;  // +30 % lighting
  shifted.convertTo(b, CV_8U);
  const GridTemplate t = grid_template(a, cv::Point2f(96.f, 103.f), 10);
  const auto r = align_template(b, t.patch, cv::Point2f(97.f, 102.f));
  ASSERT_TRUE(r);
  EXPECT_NEAR(r->position.x, 96.0 + dx, 0.05);
  EXPECT_NEAR(r->position.y, 103.0 + dy, 0.05);
  EXPECT_GT(r->ncc, 0.99);
}

class SequenceFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = tmp_.path() / "seq";
    sim::stereo::write_sequence(testing::small_sequence(0.1), dir_);
  }
  void write(const std::string& name, const std::string& text) { std::ofstream(dir_ / name) << text; }
  std::string error_of(const std::function<void()>& f) {
    try {
      f();
    } catch (const TrackError& e) {
      return e.what();
    }
    return "no error";
  }
  testing::TempDir tmp_;
  std::filesystem::path dir_;
};

TEST_F(SequenceFiles, RendererOutputLoads) {
  const Sequence s = load_sequence(dir_);
  EXPECT_EQ(s.frames.size(), 2u);
  EXPECT_EQ(s.calibration.size, cv::Size(640, 512));
  EXPECT_NEAR(s.calibration.T_camR_camL.translation().norm(), 0.5, 1e-9);
  EXPECT_EQ(load_seeds(dir_ / "seeds.yaml", s.calibration.size).size(), 10u);
  EXPECT_EQ(load_grey(s.frames[1].right, s.calibration.size).type(), CV_8UC1);
}

TEST_F(SequenceFiles, BadInputIsOneLineNamingFileAndPlace) {
  write("frames.csv", "index,t,left,right\n0,0,left/000000.png,right/000000.png\n1,zero,a.png,b.png\n");
  EXPECT_NE(error_of([&] { load_sequence(dir_); }).find("frames.csv:3: t 'zero'"), std::string::npos);
  write("frames.csv", "index,t,left,right\n0,0.1,a.png,b.png\n1,0.1,a.png,b.png\n");
  EXPECT_NE(error_of([&] { load_sequence(dir_); }).find("frames.csv:3: t must increase"), std::string::npos);
  write("frames.csv", "idx,t,left,right\n");
  EXPECT_NE(error_of([&] { load_sequence(dir_); }).find("frames.csv:1: header"), std::string::npos);
  write("seeds.yaml",
        "%YAML:1.0\nseeds_right: !!opencv-matrix\n  rows: 2\n  cols: 2\n  dt: f\n  data: [1, 2, 700, 3]\n");
  EXPECT_NE(error_of([&] {
              load_seeds(dir_ / "seeds.yaml", {640, 512});
            }).find("seeds_right row 1 (700, 3) is outside"),
            std::string::npos);
  write("stereo.yaml", "%YAML:1.0\nimage_width: 640\nimage_height: 512\n");
  EXPECT_NE(error_of([&] { load_stereo_calibration(dir_ / "stereo.yaml"); }).find("field K1 is missing"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              load_grey(dir_ / "left" / "000000.png", {1280, 1024});
            }).find("image is 640x512"),
            std::string::npos);
  EXPECT_NE(error_of([&] { load_sequence(dir_ / "nope"); }).find("not a directory"), std::string::npos);
}

// Property test: any corruption of frames.csv or stereo.yaml loads or throws TrackError.
TEST_F(SequenceFiles, MutatedFilesNeverCrash) {
  std::mt19937 rng(11);
  for (const char* name : {"frames.csv", "stereo.yaml"}) {
    std::ifstream in(dir_ / name);
    const std::string good((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    for (int trial = 0; trial < 150; ++trial) {
      std::string bad = good;
      const int edits = 1 + static_cast<int>(rng() % 4);
      for (int e = 0; e < edits; ++e) {
        const std::size_t at = rng() % bad.size();
        switch (rng() % 3) {
          case 0:
            bad[at] = static_cast<char>(rng() % 256);
            break;
          case 1:
            bad.erase(at, 1 + rng() % 8);
            break;
          default:
            bad.insert(at, 1, ",:-.0e\n["[rng() % 9]);
            break;
        }
        if (bad.empty()) bad = "x";
      }
      write(name, bad);
      try {
        load_sequence(dir_);
      } catch (const TrackError&) {
      }
    }
    write(name, good);
  }
  SUCCEED();
}

}  // namespace
}  // namespace dentmark::track
