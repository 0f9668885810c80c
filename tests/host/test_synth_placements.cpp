// Character lines and defects placed beside design features in `synth scan`
// (sim/scan): the step's shape, each planted defect's gap from its feature's footprint,
// and the truth file carrying where each was placed.
#include <gtest/gtest.h>

#include <cmath>

#include "dentmark/sim/scan/sls_scan.h"
#include "dentmark/sim/scan/truth_file.h"

namespace dentmark::sim::scan {
namespace {

PanelShape plain_with_line(double angle, double step, double width) {
  PanelShape s;
  s.width = 0.6, s.height = 0.5;
  s.crease = s.handle = s.window = false;
  s.lines.push_back({{0.3, 0.2}, angle, step, width});
  return s;
}

TEST(CharacterLine, IsASmoothStepOfItsHeightAcrossItsWidth) {
  const double angle = 0.4, step = 0.003, width = 0.012;
  const DoorPanel with(plain_with_line(angle, step, width), {});
  PanelShape none = plain_with_line(angle, step, width);
  none.lines.clear();
  const DoorPanel without(none, {});
  const Eigen::Vector2d n(-std::sin(angle), std::cos(angle));
  const Eigen::Vector2d c(0.3, 0.2);
  auto rise = [&](double off) {
    const Eigen::Vector2d p = c + off * n;
    return with.z_nominal(p.x(), p.y()) - without.z_nominal(p.x(), p.y());
  };
  EXPECT_NEAR(rise(-0.5 * width - 1e-4), 0.0, 1e-12);
  EXPECT_NEAR(rise(0.0), 0.5 * step, 1e-9);
  EXPECT_NEAR(rise(0.5 * width + 1e-4), step, 1e-12);
  EXPECT_NEAR(with.line_offset(0, c.x() + 0.01 * n.x(), c.y() + 0.01 * n.y()), 0.01, 1e-12);
  EXPECT_NEAR(with.footprint_distance("line0", c.x() + 0.02 * n.x(), c.y() + 0.02 * n.y()),
              0.02 - 0.5 * width, 1e-12);
  EXPECT_THROW((void)with.footprint_distance("handle", 0.1, 0.1), std::invalid_argument);
}

TEST(NearFeatures, DefectsLieAtTheirGapsFromTheFootprintAndTheTruthSaysSo) {
  ScanOptions o;
  o.seed = 5;
  o.spacing = 0.004;
  o.defects = 0;
  o.min_diameter = 0.009, o.max_diameter = 0.025;
  o.min_depth = 1e-4, o.max_depth = 1e-3;
  o.shape = plain_with_line(0.3, -0.003, 0.012);
  o.shape.lines.push_back({{0.3, 0.38}, 0.3, 0.002, 0.010});
  o.near_lines = {-1.0, 0.004, 0.009, 0.018};
  const SynthScan scan = synthesize_scan(o);
  ASSERT_EQ(scan.defects.size(), 8u);
  const DoorPanel probe(o.shape, {});
  const Eigen::Isometry3d T_panel_sls = scan.T_sls_panel.inverse();
  for (const TruthDefect& d : scan.defects) {
    ASSERT_TRUE(d.beside == "line0" || d.beside == "line1") << d.beside;
    const Eigen::Vector3d p = T_panel_sls * d.position;
    const double r = 0.5 * d.diameter;
    const double dist = probe.footprint_distance(d.beside, p.x(), p.y());
    if (d.gap < 0) {
      EXPECT_NEAR(d.gap, -r, 1e-12);
      EXPECT_NEAR(std::abs(probe.line_offset(d.beside == "line0" ? 0 : 1, p.x(), p.y())), 0.0, 3e-4);
    } else {
      EXPECT_NEAR(dist - r, d.gap, 3e-4) << d.beside;
      const std::string other = d.beside == "line0" ? "line1" : "line0";
      EXPECT_GT(probe.footprint_distance(other, p.x(), p.y()) - r, 0.0249);
    }
  }
  const nlohmann::json j = truth_to_json(truth_of(scan, o.shape.width, o.shape.height));
  EXPECT_EQ(j["defects"][0]["feature"], scan.defects[0].beside);
  EXPECT_DOUBLE_EQ(j["defects"][1]["gap"].get<double>(), scan.defects[1].gap);
}

TEST(NearFeatures, BesideEveryFeatureOfTheDoor) {
  ScanOptions o;
  o.seed = 9;
  o.spacing = 0.004;
  o.defects = 0;
  o.min_diameter = 0.009, o.max_diameter = 0.02;
  o.near_features = {0.004, 0.02};
  const SynthScan scan = synthesize_scan(o);
  const DoorPanel probe(o.shape, {});
  const Eigen::Isometry3d T_panel_sls = scan.T_sls_panel.inverse();
  int placed = 0;
  for (const TruthDefect& d : scan.defects) {
    const Eigen::Vector3d p = T_panel_sls * d.position;
    EXPECT_NEAR(probe.footprint_distance(d.beside, p.x(), p.y()) - 0.5 * d.diameter, d.gap, 3e-4) << d.beside;
    ++placed;
  }
  EXPECT_EQ(placed, 8);  // border, handle, crease, window at two gaps each
}

TEST(NearFeatures, NonsenseIsRefused) {
  ScanOptions o;
  o.spacing = 0.004;
  o.near_features = {-0.01};
  EXPECT_THROW(synthesize_scan(o), std::invalid_argument);
  o.near_features = {};
  o.shape.lines.push_back({{0.5, 0.3}, 0.0, 0.05, 0.012});
  EXPECT_THROW(synthesize_scan(o), std::invalid_argument);
}

TEST(SensorPose, ARolledSensorSeesTheSameScanTurnedAboutItsAxis) {
  // The benchmark's layouts turn the scan in the sensor frame: the same samples, the
  // truth turned with them.
  ScanOptions o;
  o.seed = 3;
  o.spacing = 0.004;
  o.tilt = Eigen::Vector3d(0.1, -0.15, 0.0);
  const SynthScan level = synthesize_scan(o);
  o.tilt->z() = 0.6;
  const SynthScan rolled = synthesize_scan(o);
  ASSERT_EQ(level.vertices.size(), rolled.vertices.size());
  ASSERT_EQ(level.triangles, rolled.triangles);
  const Eigen::AngleAxisd roll(0.6, Eigen::Vector3d::UnitZ());
  for (std::size_t k = 0; k < level.vertices.size(); ++k)
    ASSERT_LT((roll * level.vertices[k].cast<double>() - rolled.vertices[k].cast<double>()).norm(), 1e-6)
        << k;
  ASSERT_EQ(level.defects.size(), rolled.defects.size());
  for (std::size_t k = 0; k < level.defects.size(); ++k) {
    EXPECT_LT((roll * level.defects[k].position - rolled.defects[k].position).norm(), 1e-12);
    EXPECT_LT((roll * level.defects[k].normal - rolled.defects[k].normal).norm(), 1e-12);
  }
  // Its own yaw and pitch: not the ones drawn for the seed.
  o.tilt.reset();
  EXPECT_GT((synthesize_scan(o).T_sls_panel.linear() - level.T_sls_panel.linear()).norm(), 1e-3);
}

}  // namespace
}  // namespace dentmark::sim::scan
