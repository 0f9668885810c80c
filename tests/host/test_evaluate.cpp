// Scoring: matching radius, sign, size classes, false alarms on features.
#include <gtest/gtest.h>

#include "dentmark/host/report/evaluate.h"

namespace dentmark::report {
namespace {

LabelledDefect item(double x, double diameter, double height) {
  LabelledDefect d;
  d.defect_class = height < 0 ? "dent" : "bump";
  d.defect.position = {x, 0, 1};
  d.defect.normal = {0, 0, -1};
  d.defect.diameter = diameter;
  d.defect.height = height;
  return d;
}

TEST(Evaluate, HolesMatchOnlyHoles) {
  TruthFile t;
  t.panel_area = 1.0;
  t.defects = {item(0.0, 0.008, 0.0), item(0.1, 0.012, 2e-4)};
  t.defects[0].defect_class = "hole";
  DefectsFile d;
  d.defects = {item(0.0005, 0.008, 0.0), item(0.1, 0.012, 0.0)};
  d.defects[0].defect_class = "hole";  // the hole
  d.defects[1].defect_class = "hole";  // a hole where a bump is: wrong kind
  const Evaluation e = evaluate(t, d);
  EXPECT_EQ(e.matched, 1);
  EXPECT_EQ(e.wrong_sign, 1);
  EXPECT_EQ(e.classes[2].total, 1);
  EXPECT_EQ(e.classes[2].found, 1);
  EXPECT_EQ(e.depth_matched, 0);  // a hole has no depth to compare
  EXPECT_NEAR(e.max_position_error, 0.0005, 1e-9);
}

TEST(Evaluate, MatchesCountsAndErrors) {
  TruthFile t;
  t.panel_area = 2.0;
  t.defects = {item(0.0, 0.012, -6e-5), item(0.1, 0.006, 2e-4), item(0.2, 0.02, -1e-3)};
  t.features = {{"handle", {{0.5, 0, 1}}, 0.03}};
  DefectsFile d;
  d.defects = {item(0.0008, 0.01, -5.5e-5),  // matched, 0.8 mm, 5 µm
               item(0.1, 0.006, -2e-4),      // wrong sign
               item(0.5, 0.05, 1e-3),        // on the handle
               item(0.9, 0.01, 1e-4)};       // plain false alarm
  // Offsets along the truth normal do not count as position error.
  d.defects[0].defect.position.z() += 0.003;
  const Evaluation e = evaluate(t, d);
  EXPECT_EQ(e.matched, 1);
  EXPECT_EQ(e.wrong_sign, 1);
  EXPECT_EQ(e.false_alarms, 3);
  EXPECT_EQ(e.on_features, 1);
  EXPECT_NEAR(e.false_alarms_per_m2(), 1.5, 1e-12);
  EXPECT_NEAR(e.max_position_error, 0.0008, 1e-9);
  EXPECT_NEAR(e.max_depth_error, 5e-6, 1e-12);
  EXPECT_EQ(e.depth_within_tolerance, 1);
  ASSERT_EQ(e.classes.size(), 3u);
  EXPECT_EQ(e.classes[2].total, 0);  // no holes
  EXPECT_EQ(e.classes[0].total, 2);  // 12 mm / 60 µm and 20 mm / 1 mm
  EXPECT_EQ(e.classes[0].found, 1);
  EXPECT_EQ(e.classes[1].total, 2);  // 6 mm / 0.2 mm and 20 mm / 1 mm
  EXPECT_EQ(e.classes[1].found, 0);
  Evaluation pooled = e;
  pooled.add(e);
  EXPECT_EQ(pooled.matched, 2);
  EXPECT_NEAR(pooled.area, 4.0, 1e-12);
}

TEST(Evaluate, TooFarIsNotAMatch) {
  TruthFile t;
  t.panel_area = 1.0;
  t.defects = {item(0.0, 0.008, -1e-4)};
  DefectsFile d;
  d.defects = {item(0.0051, 0.008, -1e-4)};  // 5.1 mm > max(5 mm, 4 mm)
  EXPECT_EQ(evaluate(t, d).matched, 0);
}

}  // namespace
}  // namespace dentmark::report
