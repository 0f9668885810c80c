// Operator-free start: a panel model taught on one rendered run acquires a later panel
// of the same model (elsewhere on the line, turned, under other lighting, other noise)
// without seeds; the tracked motion is checked against that run's ground truth. A
// model of another panel, or a bad model file, is a clear failure, never a wrong lock.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <random>

#include "dentmark/firmware/track/model_search.h"
#include "dentmark/firmware/track/panel_model.h"
#include "dentmark/firmware/track/replay.h"
#include "dentmark/firmware/track/sequence.h"
#include "dentmark/firmware/track/track_error.h"
#include "sequence_fixture.h"

namespace dentmark::track {
namespace {

using testing::TempDir;

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const TrackError& e) {
    return e.what();
  }
  return "(no TrackError)";
}

// A model taught at the first frame of a 1 s run of the default panel.
struct Taught {
  TempDir tmp;
  std::filesystem::path model = tmp.path() / "model.yaml";
  explicit Taught(bool rear_door = false) {
    auto o = testing::small_sequence(1.0);
    o.rear_door = rear_door;
    sim::stereo::write_sequence(o, tmp.path() / "teach");
    save_panel_model(teach_sequence(tmp.path() / "teach"), model);
  }
};

struct Later {
  double shift;  // m along the line from the taught position
  double yaw;    // rad
  double gain;   // lighting relative to the taught run
};

class TeachAndAcquire : public ::testing::TestWithParam<Later> {};

TEST_P(TeachAndAcquire, LaterPanelIsAcquiredWithoutSeedsAndTrackedWithinTheTarget) {
  static const Taught taught;
  const Later later = GetParam();
  TempDir tmp;
  auto o = testing::small_sequence(2.0);
  o.start_offset = later.shift;
  o.extra_yaw = later.yaw;
  o.gain = later.gain;
  o.seed = 11;
  o.seed_error = 60.0;  // the sequence's own seeds are useless: only the model can start it
  const auto dir = tmp.path() / "later";
  sim::stereo::write_sequence(o, dir);
  const ReplayResult r = replay_sequence_with_model(dir, taught.model);
  const MotionErrors e = compare_with_truth(r, dir / "truth.csv", dir / "eval_points.csv");
  std::printf("shift %.2f m, yaw %.3f rad, gain %.2f: %d features, mean %.3f mm, worst %.3f mm\n",
              later.shift, later.yaw, later.gain, r.reference_features, e.mean * 1e3, e.worst * 1e3);
  EXPECT_GE(r.reference_features, 8);
  EXPECT_EQ(e.failed, 0);
  EXPECT_EQ(e.frames, 21);
  // Half resolution: twice the full-resolution targets (as test_tracker.cpp).
  EXPECT_LT(e.mean, 1.0e-3);
  EXPECT_LT(e.worst, 3.0e-3);
}

INSTANTIATE_TEST_SUITE_P(AlongTheLine, TeachAndAcquire,
                         ::testing::Values(Later{0.04, 0.0, 1.0}, Later{0.15, 0.02, 0.7},
                                           Later{-0.30, -0.03, 1.3}, Later{0.20, -0.02, 1.25}),
                         [](const ::testing::TestParamInfo<Later>& p) {
                           const auto n = [](double v) {
                             return (v < 0 ? "Minus" : "") + std::to_string(std::lround(std::abs(v)));
                           };
                           return "Shift" + n(p.param.shift * 100) + "cmYaw" + n(p.param.yaw * 1000) +
                                  "mradGain" + n(p.param.gain * 100) + "pc";
                         });

TEST(ModelSearch, TheFoundFeaturesAreTheTaughtOnes) {
  // The consensus must pick each taught corner, not a look-alike: its camR position
  // agrees with where the renderer puts that corner.
  Taught taught;
  const PanelModel model = load_panel_model(taught.model);
  TempDir tmp;
  auto o = testing::small_sequence(0.0);
  o.start_offset = 0.3;  // the door's far end is at the edge of camL's view
  o.extra_yaw = 0.03;
  o.gain = 0.8;
  o.seed = 5;
  o.seed_error = 0.0;  // seeds.yaml then holds the true camR corners
  sim::stereo::write_sequence(o, tmp.path() / "s");
  const Sequence seq = load_sequence(tmp.path() / "s");
  const auto truth = load_seeds(tmp.path() / "s" / "seeds.yaml", seq.calibration.size);
  const cv::Mat l = load_grey(seq.frames[0].left, seq.calibration.size),
                rr = load_grey(seq.frames[0].right, seq.calibration.size);
  const ModelSearchResult found = search_model(seq.calibration, l, rr, model);
  EXPECT_GE(found.found, 6);
  // Model feature i was taught from seed i of the teach run (all 10 were usable).
  ASSERT_EQ(model.features.size(), truth.size());
  for (std::size_t i = 0; i < truth.size(); ++i)
    if (found.seeds_right[i]) {
      EXPECT_LT(cv::norm(*found.seeds_right[i] - truth[i]), 1.5) << "feature " << i;
    }
}

TEST(ModelSearch, AModelOfAnotherPanelDoesNotLock) {
  const Taught rear(true);
  TempDir tmp;
  auto o = testing::small_sequence(0.5);
  o.start_offset = 0.05;
  sim::stereo::write_sequence(o, tmp.path() / "front");
  const std::string e = error_of([&] { replay_sequence_with_model(tmp.path() / "front", rear.model); });
  EXPECT_NE(e.find("panel model not found"), std::string::npos) << e;
  EXPECT_NE(e.find("model.yaml"), std::string::npos) << e;
  EXPECT_NE(e.find("000000.png"), std::string::npos) << e;
}

TEST(ModelSearch, APanelOutOfViewDoesNotLock) {
  const Taught taught;
  TempDir tmp;
  auto o = testing::small_sequence(0.0);
  o.start_offset = 3.0;  // the door is still up the line: only the background is seen
  sim::stereo::write_sequence(o, tmp.path() / "empty");
  const std::string e = error_of([&] { replay_sequence_with_model(tmp.path() / "empty", taught.model); });
  EXPECT_NE(e.find("panel model not found"), std::string::npos) << e;
}

TEST(PanelModel, SavesAndLoadsExactly) {
  const Taught taught;
  const PanelModel m = load_panel_model(taught.model, {640, 512});
  TempDir tmp;
  save_panel_model(m, tmp.path() / "again.yaml");
  const PanelModel again = load_panel_model(tmp.path() / "again.yaml");
  ASSERT_EQ(again.features.size(), m.features.size());
  EXPECT_EQ(m.features.size(), 10u);
  EXPECT_EQ(again.levels, m.levels);
  for (std::size_t i = 0; i < m.features.size(); ++i) {
    EXPECT_EQ(again.features[i].p_camL, m.features[i].p_camL);
    for (int l = 0; l < m.levels; ++l)
      EXPECT_EQ(cv::norm(again.features[i].right[l], m.features[i].right[l], cv::NORM_INF), 0.0);
  }
  // The layout is in metres, in camL at the teach frame: 2.8 m in front of the pair.
  for (const auto& f : m.features) EXPECT_NEAR(f.p_camL.z(), 2.8, 0.15);
}

TEST(PanelModel, BadModelFilesAreOneClearLineNamingFileAndField) {
  const Taught taught;
  TempDir tmp;
  const auto missing = tmp.path() / "nope.yaml";
  std::string e = error_of([&] { load_panel_model(missing); });
  EXPECT_NE(e.find("nope.yaml: no such file"), std::string::npos) << e;

  const auto garbage = tmp.path() / "garbage.yaml";
  std::ofstream(garbage) << "%YAML:1.0\n---\nlayout_camL: [1, 2\n  : :\n";
  e = error_of([&] { load_panel_model(garbage); });
  EXPECT_NE(e.find("garbage.yaml"), std::string::npos) << e;

  // The taught file with one field broken at a time.
  std::string text;
  {
    std::ifstream in(taught.model);
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  auto broken = [&](const std::string& from, const std::string& to) {
    const auto p = tmp.path() / "broken.yaml";
    std::string t = text;
    const auto at = t.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    t.replace(at, from.size(), to);
    std::ofstream(p, std::ios::trunc) << t;
    return error_of([&] { load_panel_model(p, {640, 512}); });
  };
  e = broken("templates:", "templatez:");
  EXPECT_NE(e.find("broken.yaml: field templates is missing"), std::string::npos) << e;
  e = broken("layout_camL: !!opencv-matrix\n   rows: 10", "layout_camL: !!opencv-matrix\n   rows: 9");
  EXPECT_NE(e.find("field layout_camL"), std::string::npos) << e;
  e = broken("levels: 3", "levels: 2");
  EXPECT_NE(e.find("field templates[0].left"), std::string::npos) << e;
  e = broken("image_width: 640", "image_width: 1280");
  EXPECT_NE(e.find("broken.yaml: field image_width: the model was taught on 1280x512"), std::string::npos)
      << e;
  EXPECT_EQ(e.find('\n'), std::string::npos);

  // A model taught on other cameras: through replay, naming the model file.
  TempDir seq;
  auto o = testing::small_sequence(0.0);
  o.width = 800;
  sim::stereo::write_sequence(o, seq.path() / "s");
  e = error_of([&] { replay_sequence_with_model(seq.path() / "s", taught.model); });
  EXPECT_NE(e.find("model.yaml: field image_width"), std::string::npos) << e;
}

TEST(PanelModel, MutatedModelFilesNeverCrash) {
  // Anything but a model or a TrackError (a crash, another exception, a huge
  // allocation from a corrupted matrix header) fails this test.
  const Taught taught;
  std::string good;
  {
    std::ifstream in(taught.model);
    good.assign(std::istreambuf_iterator<char>(in), {});
  }
  TempDir tmp;
  const auto path = tmp.path() / "mutated.yaml";
  std::mt19937 rng(5);
  int loaded = 0;
  for (int trial = 0; trial < 200; ++trial) {
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
          bad.insert(at, 1, ",:-.0e\n[9"[rng() % 10]);
          break;
      }
      if (bad.empty()) bad = "x";
    }
    std::ofstream(path, std::ios::trunc) << bad;
    try {
      const PanelModel m = load_panel_model(path, {640, 512});
      ++loaded;
      for (const auto& f : m.features) ASSERT_EQ(f.left.size(), static_cast<std::size_t>(m.levels));
    } catch (const TrackError&) {
    }
  }
  std::printf("%d of 200 mutated models still loaded (edits inside numbers)\n", loaded);
}

TEST(PanelModel, TeachAtALaterFrameFollowsThePanelThere) {
  TempDir tmp;
  auto o = testing::small_sequence(1.0);
  o.speed = 0.1;  // 10 cm in the second
  sim::stereo::write_sequence(o, tmp.path() / "s");
  const PanelModel first = teach_sequence(tmp.path() / "s");
  const PanelModel last = teach_sequence(tmp.path() / "s", 10);
  ASSERT_EQ(first.features.size(), last.features.size());
  // The layouts differ by the true motion of frame 10 (truth.csv row 10).
  std::ifstream truth(tmp.path() / "s" / "truth.csv");
  std::string line;
  for (int k = 0; k <= 11; ++k) std::getline(truth, line);
  std::stringstream ss(line);
  std::vector<double> v;
  for (std::string cell; std::getline(ss, cell, ',');) v.push_back(std::stod(cell));
  Transform m = Transform::Identity();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) m.matrix()(r, c) = v[static_cast<std::size_t>(2 + 4 * r + c)];
  for (std::size_t i = 0; i < first.features.size(); ++i)
    EXPECT_LT((m * first.features[i].p_camL - last.features[i].p_camL).norm(), 4e-3) << i;
  EXPECT_EQ(error_of([&] {
              teach_sequence(tmp.path() / "s", 99);
            }).find("frames.csv: no frame with index 99") == std::string::npos,
            false);
}

}  // namespace
}  // namespace dentmark::track
