// The renderer's promise: corners at their true sub-pixel positions, ground truth that
// matches the images, and nothing half-written.
#include <gtest/gtest.h>

#include <fstream>

#include "dentmark/firmware/track/sequence.h"
#include "dentmark/firmware/track/template_align.h"
#include "dentmark/sim/stereo/panel_motion.h"
#include "dentmark/sim/stereo/sequence_writer.h"
#include "dentmark/sim/stereo/stereo_renderer.h"
#include "sequence_fixture.h"

namespace dentmark::sim::stereo {
namespace {

TEST(StereoRenderer, CornersMoveByTheirTrueSubPixelDisplacement) {
  const StereoRig rig = make_rig({640, 512}, 870.0, 0.5, 0.09);
  const StereoRenderer r(rig, make_door());
  Transform pose0 = Transform::Identity();
  pose0.linear() = Eigen::AngleAxisd(0.12, Eigen::Vector3d::UnitY()).toRotationMatrix();
  pose0.translation() = Eigen::Vector3d(0.2, 0.2, 2.8);
  const Transform pose1 = Transform(Eigen::Translation3d(0.00123, -0.00071, 0.004)) * pose0;
  RenderConditions c;
  c.noise_sigma = 0.0;
  c.blur_sigma = 0.8;
  cv::RNG rng(1);
  for (Eye eye : {Eye::kLeft, Eye::kRight}) {
    const cv::Mat a = r.render(eye, pose0, c, rng), b = r.render(eye, pose1, c, rng);
    for (const auto& f : r.door().features) {
      const Eigen::Vector3d p(f.x(), f.y(), 0.0);
      const cv::Point2d pa = r.project(eye, pose0, p), pb = r.project(eye, pose1, p);
      const auto t = track::grid_template(a, cv::Point2f(pa), 10);
      const auto m = track::align_template(b, t.patch, cv::Point2f(pb) - t.offset + cv::Point2f(0.4f, -0.3f));
      ASSERT_TRUE(m);
      EXPECT_NEAR(m->position.x + t.offset.x, pb.x, 0.1);
      EXPECT_NEAR(m->position.y + t.offset.y, pb.y, 0.1);
    }
  }
}

TEST(StereoRenderer, SequenceCarriesConsistentTruthAndSeeds) {
  track::testing::TempDir tmp;
  auto o = track::testing::small_sequence(0.5);
  o.seed_error = 2.0;
  write_sequence(o, tmp.path() / "seq");
  const auto seq = track::load_sequence(tmp.path() / "seq");
  ASSERT_EQ(seq.frames.size(), 6u);
  EXPECT_DOUBLE_EQ(seq.frames[5].t, 0.5);
  const auto seeds = track::load_seeds(tmp.path() / "seq" / "seeds.yaml", seq.calibration.size);
  // features.csv holds the corners in camL at frame 0: the seeds are their camR images ± 2 px.
  std::ifstream in(tmp.path() / "seq" / "features.csv");
  std::string header;
  std::getline(in, header);
  std::vector<Eigen::Vector3d> corners;
  double x, y, z;
  char comma;
  while (in >> x >> comma >> y >> comma >> z) corners.emplace_back(x, y, z);
  ASSERT_EQ(corners.size(), seeds.size());
  const auto proj = seq.calibration.project(track::Cam::kRight, corners);
  for (std::size_t i = 0; i < seeds.size(); ++i) {
    EXPECT_LE(std::abs(seeds[i].x - proj[i].x), 2.0 + 1e-3);
    EXPECT_LE(std::abs(seeds[i].y - proj[i].y), 2.0 + 1e-3);
  }
  // truth.csv at t = 0.5 s: 7 mm along the line.
  PanelMotion m;
  m.speed = o.speed;
  m.vibration = 0.0;
  EXPECT_NEAR(m.motion(0.5).translation().norm(), 0.007, 1e-12);
}

TEST(StereoRenderer, RefusesANonEmptyDirectoryAndLeavesNothingBehind) {
  track::testing::TempDir tmp;
  std::ofstream(tmp.path() / "keep.txt") << "x";
  EXPECT_THROW(write_sequence(track::testing::small_sequence(0.1), tmp.path()), SequenceError);
  auto bad = track::testing::small_sequence(0.1);
  bad.fps = -1;
  EXPECT_THROW(write_sequence(bad, tmp.path() / "new"), SequenceError);
  EXPECT_FALSE(std::filesystem::exists(tmp.path() / "new"));
  std::size_t entries = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(tmp.path())) ++entries;
  EXPECT_EQ(entries, 1u);
}

}  // namespace
}  // namespace dentmark::sim::stereo
