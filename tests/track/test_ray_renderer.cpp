// The ray-traced renderer (sim/stereo_raytrace) against closed-form truth: the lens
// model's inverse, the calibration it writes as the tracker reads it, corner positions
// in its supersampled images, the colour pipeline and the conveyor's stop.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "../support/temp_dir.h"
#include "accuracy_report.h"
#include "dentmark/firmware/track/stereo_calibration.h"
#include "dentmark/sim/stereo_raytrace/conveyor.h"
#include "dentmark/sim/stereo_raytrace/lens.h"
#include "dentmark/sim/stereo_raytrace/ray_sequence.h"
#include "dentmark/sim/stereo_raytrace/ray_tracer.h"
#include "dentmark/sim/stereo_raytrace/sensor.h"

namespace dentmark::sim::raytrace {
namespace {

BrownConrady strong_lens() {
  return {1740.0, 1741.0, 645.0, 509.0, {-0.085, 0.11, 3e-4, -2e-4, -0.01}};
}

TEST(RayRenderer, LensUnprojectInvertsTheDistortion) {
  const BrownConrady lens = strong_lens();
  double worst = 0.0;
  for (double u = 0; u <= 1280; u += 64)
    for (double v = 0; v <= 1024; v += 64) {
      const Eigen::Vector2d xy = lens.unproject({u, v});
      worst = std::max(worst, (lens.project_normalized(xy) - Eigen::Vector2d(u, v)).norm());
    }
  EXPECT_LT(worst, 1e-6);
  // The corners of the image are distorted by several pixels: the test is not trivial.
  const Eigen::Vector2d xy = lens.unproject({0, 0});
  EXPECT_GT((Eigen::Vector2d(lens.fx * xy.x() + lens.cx, lens.fy * xy.y() + lens.cy) - Eigen::Vector2d(0, 0))
                .norm(),
            5.0);
}

TEST(RayRenderer, WrittenCalibrationProjectsTheFeaturesOntoTheSeeds) {
  test::TempDir tmp;
  RaySequenceOptions o;
  o.width = 640;
  o.height = 512;
  o.focal_px = 870.0;
  o.seconds = 0.0;
  o.seed_error = 0.0;
  write_ray_sequence(o, tmp.path() / "seq");
  const auto calib = track::load_stereo_calibration(tmp.path() / "seq" / "stereo.yaml");
  const auto seeds = track::load_seeds(tmp.path() / "seq" / "seeds.yaml", calib.size);
  const auto feats = track::testing::read_csv_numbers(tmp.path() / "seq" / "features.csv");
  ASSERT_EQ(seeds.size(), 10u);
  ASSERT_EQ(feats.size(), 10u);
  for (std::size_t i = 0; i < seeds.size(); ++i) {
    const cv::Point2f p =
        calib.project(track::Cam::kRight, {Eigen::Vector3d(feats[i][0], feats[i][1], feats[i][2])})[0];
    EXPECT_LT(cv::norm(p - seeds[i]), 1e-3) << "feature " << i;
  }
}

TEST(RayRenderer, EdgesLandWhereTheLensProjectsThem) {
  // One camera with strong distortion, the door fronto-parallel at 2.8 m, no motion: the
  // window frame's lower edge (dark above, bright skin below) crosses a column of pixels;
  // the mixed pixel's level gives the edge's position to the supersampling's 1/64 px.
  const BrownConrady lens = strong_lens();
  const RayTracer tracer(lens, Eigen::Isometry3d::Identity(), {1280, 1024}, 8);
  const Door door = make_door();
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(0.05, 0.25, 2.8);
  Lighting flat;
  flat.gradient.setZero();
  const cv::Mat3f img = tracer.render(door, std::nullopt, {pose}, flat);
  for (double x : {-0.4, -0.1, 0.2, 0.4}) {
    const Eigen::Vector3d p = pose * Eigen::Vector3d(x, -0.05, 0.0);
    const Eigen::Vector2d truth = lens.project_normalized(p.head<2>() / p.z());
    const int u = static_cast<int>(std::round(truth.x())), r = static_cast<int>(std::round(truth.y()));
    const double dark = img(r - 3, u)[1], bright = img(r + 3, u)[1], mixed = img(r, u)[1];
    ASSERT_GT(bright - dark, 0.3);
    const double edge = r - 0.5 + (bright - mixed) / (bright - dark);
    // The edge is curved by the distortion; across one pixel that is ~0.001 px.
    EXPECT_NEAR(edge, truth.y(), 0.03) << "x = " << x;
  }
}

TEST(RayRenderer, BayerPipelineKeepsColoursAndBalancesGrey) {
  const RayTracer tracer(BrownConrady{870.0, 870.0, 31.5, 31.5}, Eigen::Isometry3d::Identity(), {64, 64}, 1);
  std::mt19937_64 rng(3);
  SensorOptions s;
  s.defocus_radius = 0.0;
  cv::Mat3f red(64, 64, cv::Vec3f(0.6f, 0.25f, 0.1f)), grey(64, 64, cv::Vec3f(0.4f, 0.4f, 0.4f));
  const cv::Mat3b r = expose(red, tracer.corner_rays(), s, rng),
                  g = expose(grey, tracer.corner_rays(), s, rng);
  const cv::Rect inner(8, 8, 48, 48);
  const cv::Scalar mr = cv::mean(r(inner)), mg = cv::mean(g(inner));  // B, G, R
  EXPECT_GT(mr[2], mr[1] + 40);
  EXPECT_GT(mr[1], mr[0] + 20);
  EXPECT_NEAR(mg[0], mg[1], 3.0);
  EXPECT_NEAR(mg[2], mg[1], 3.0);
  // Reflectance 0.4 at 14000 e-/unit, green response 0.8, 16000 e- full scale, gamma 2.2
  // (vignetting under 0.2 % this near the axis).
  EXPECT_NEAR(mg[1], 255.0 * std::pow(0.4 * 14000.0 * 0.8 / 16000.0, 1.0 / 2.2), 4.0);
  // Photon noise: a flat field is not flat.
  cv::Scalar m, sd;
  cv::meanStdDev(g(inner), m, sd);
  EXPECT_GT(sd[1], 0.5);
}

TEST(RayRenderer, ConveyorStopsAndRestartsSmoothly) {
  Conveyor c;
  c.speed = 0.05;
  c.stop_at = 1.0;
  c.stop_for = 1.0;
  c.ramp = 0.2;
  EXPECT_NEAR(c.travel(1.0), 0.05, 1e-12);
  EXPECT_NEAR(c.travel(1.2), 0.05 + 0.05 * 0.1, 1e-12);  // half the ramp's distance at full speed
  EXPECT_NEAR(c.travel(1.7), c.travel(2.1), 1e-12);      // at rest
  EXPECT_NEAR(c.travel(2.4) - c.travel(2.2), 0.05 * 0.1, 1e-12);
  EXPECT_NEAR(c.travel(3.4) - c.travel(3.0), 0.05 * 0.4, 1e-12);  // full speed again
  for (double t = 0.0; t < 4.0; t += 0.01) EXPECT_GE(c.travel(t + 0.01), c.travel(t) - 1e-15);
}

}  // namespace
}  // namespace dentmark::sim::raytrace
