// The tracker's accuracy at the station's full geometry (2.8 m, 0.5 m baseline,
// f = 1740 px at 1280 x 1024; f = 870 px at 640 x 480) on two independent image models:
// sim/stereo (polygons, box-filtered edges, Gaussian blur and noise) and
// sim/stereo_raytrace (ray traced, distorted lenses, defocus, Bayer, Poisson noise,
// motion blur). The same targets hold on both.
#include <gtest/gtest.h>

#include "accuracy_report.h"
#include "raytrace_cache.h"

namespace dentmark::track {
namespace {

using testing::AccuracyReport;
using testing::measure;

sim::raytrace::RaySequenceOptions ray(double seconds, double fps = 10.0) {
  sim::raytrace::RaySequenceOptions o;
  o.seconds = seconds;
  o.fps = fps;
  return o;
}

sim::stereo::SequenceOptions poly(double seconds, double fps = 10.0) {
  sim::stereo::SequenceOptions o;
  o.seconds = seconds;
  o.fps = fps;
  return o;
}

template <class Options>
Options vga(Options o) {
  o.width = 640;
  o.height = 480;
  o.focal_px = 870.0;
  return o;
}

AccuracyReport run(const std::string& name, const std::filesystem::path& dir) {
  const AccuracyReport r = measure(dir);
  r.print(name);
  return r;
}

TEST(TwoRenderers, Clean1280x1024) {
  for (const auto& r : {run("polygon clean", testing::polygon_rendered("clean", poly(3.9))),
                        run("ray clean", testing::ray_traced("clean", ray(3.9)))}) {
    EXPECT_EQ(r.failed, 0);
    EXPECT_EQ(r.frames.size(), 40u);
    EXPECT_LE(r.mean, 0.5e-3);
    EXPECT_LE(r.worst, 1.5e-3);
  }
}

TEST(TwoRenderers, Occluded1280x1024) {
  auto p = poly(3.9);
  p.occlude = true;
  auto q = ray(3.9);
  q.occlude = true;
  for (const auto& r : {run("polygon occluded", testing::polygon_rendered("occluded", p)),
                        run("ray occluded", testing::ray_traced("occluded", q))}) {
    EXPECT_EQ(r.failed, 0);
    EXPECT_LE(r.mean, 0.8e-3);
    EXPECT_LE(r.worst, 2.0e-3);
  }
}

TEST(TwoRenderers, Vga640x480) {
  for (const auto& r : {run("polygon 640x480", testing::polygon_rendered("vga", vga(poly(3.9)))),
                        run("ray 640x480", testing::ray_traced("vga", vga(ray(3.9))))}) {
    EXPECT_EQ(r.failed, 0);
    EXPECT_LE(r.mean, 1.5e-3);
  }
}

TEST(TwoRenderers, SixtyFramesAt2HzOccluded) {
  auto p = poly(29.5, 2.0);
  p.occlude = true;
  auto q = ray(29.5, 2.0);
  q.occlude = true;
  for (const auto& r : {run("polygon 2 Hz occluded", testing::polygon_rendered("long", p)),
                        run("ray 2 Hz occluded", testing::ray_traced("long", q))}) {
    EXPECT_EQ(r.failed, 0);
    EXPECT_EQ(r.frames.size(), 60u);
    EXPECT_LE(r.mean, 0.8e-3);
    EXPECT_LE(r.worst, 2.0e-3);
  }
}

// A fast line (5 cm/s) that stops for a second and starts again: the filtered motion
// must not lag the truth by over 1 mm in the frames after the stop or the restart.
TEST(TwoRenderers, StopAndGoWithoutLag) {
  auto p = poly(3.9);
  p.speed = 0.05;
  p.stop_at = 1.2;
  p.stop_for = 1.2;
  auto q = ray(3.9);
  q.speed = 0.05;
  q.stop_at = 1.2;
  q.stop_for = 1.2;
  for (const auto& r : {run("polygon stop-and-go", testing::polygon_rendered("stopgo", p)),
                        run("ray stop-and-go", testing::ray_traced("stopgo", q))}) {
    EXPECT_EQ(r.failed, 0);
    for (const auto& f : r.frames) {
      if ((f.t >= 1.2 && f.t <= 1.8) || (f.t >= 2.4 && f.t <= 3.0)) {
        EXPECT_LE(f.worst, 1.0e-3) << "frame " << f.index << " at " << f.t << " s";
      }
    }
  }
}

// What the error was made of: without the conveyor's line every M(k) carries the
// first frame's tilt (its depth noise on a wide, short layout), 1-2 mm at the lower
// door, almost all of it along the optical axis.
TEST(TwoRenderers, WithoutTheLineTheFirstFramesTiltDominates) {
  TrackerOptions off;
  off.line.enabled = false;
  const AccuracyReport r = measure(testing::ray_traced("clean", ray(3.9)), off);
  r.print("ray clean, no line model");
  EXPECT_GT(r.mean, 0.5e-3);
  EXPECT_GT(r.axis.z(), 3.0 * std::max(r.axis.x(), r.axis.y()));
  double centre_z = 0.0;
  for (const auto& f : r.frames) centre_z += f.signed_centre.z() / static_cast<double>(r.frames.size());
  EXPECT_GT(std::abs(centre_z), 0.5e-3) << "a bias common to the frames, not noise";
}

// A panel that really turns (2 degrees over the run) is not a plain conveyor: the
// tracker must report the turn rather than hold the rotation at none.
TEST(TwoRenderers, FollowsAPanelThatTurns) {
  auto q = ray(3.9);
  q.turn_rate = 0.01;  // rad/s
  const AccuracyReport r = run("ray turning", testing::ray_traced("turning", q));
  EXPECT_EQ(r.failed, 0);
  EXPECT_LE(r.mean, 1.0e-3);
  EXPECT_LE(r.worst, 3.0e-3);
}

// Each frame's expected error (FrameResult::expected_error) against its true error,
// pooled over both renderers, both sizes and a panel that turns (Pearson correlation),
// and its scale.
TEST(TwoRenderers, ExpectedErrorTracksTheTrueError) {
  std::vector<double> expected, actual;
  for (const auto& r :
       {measure(testing::polygon_rendered("clean", poly(3.9))),
        measure(testing::ray_traced("clean", ray(3.9))),
        measure(testing::polygon_rendered("vga", vga(poly(3.9)))),
        measure(testing::ray_traced("vga", vga(ray(3.9)))), measure(testing::ray_traced("turning", [] {
          auto q = ray(3.9);
          q.turn_rate = 0.01;
          return q;
        }()))})
    for (const auto& f : r.frames)
      if (f.ok && f.index > 0) expected.push_back(f.expected_error), actual.push_back(f.mean);
  const double rho = testing::pearson(expected, actual);
  double se = 0, sa = 0;
  for (std::size_t i = 0; i < expected.size(); ++i) se += expected[i], sa += actual[i];
  std::printf(
      "expected vs true error over %zu frames: correlation %.2f, mean expected %.3f mm, true %.3f mm\n",
      expected.size(), rho, 1e3 * se / expected.size(), 1e3 * sa / actual.size());
  EXPECT_GT(rho, 0.45);
  EXPECT_GT(se / sa, 0.5);
  EXPECT_LT(se / sa, 2.0);
}

}  // namespace
}  // namespace dentmark::track
