// End to end on scans with outliers: coarse noisy doors, lone and clustered outlier
// vertices, outliers behind the skin; none is reported as a defect.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <random>
#include <set>
#include <tuple>

#include "dentmark/host/detect/detector.h"
#include "dentmark/host/ingest/cloud_mesher.h"
#include "dentmark/host/report/defects_json.h"
#include "dentmark/host/report/evaluate.h"
#include "dentmark/host/report/pictures.h"
#include "dentmark/host/report/scan_truth.h"
#include "dentmark/sim/scan/sls_scan.h"
#include "detect_scans.h"

namespace dentmark {
namespace {

using namespace detect_test;

TEST(Detect, ACoarseNoisyDoorReportsNoDesignFeatureAsADefect) {
  // 0.8 mm spacing and 40 um of noise, twice the target's: the crease's rounding shows
  // in the pixels' residuals only in pieces, which were reported as 6-8 dents along it
  // (the fold line is now where the fits of either side meet); and beside the handle,
  // with most of a window left out, a fit of the rest extrapolated by 0.7 mm (a false
  // dent; such a window now widens). Every defect of 10 mm or more is still found.
  SKIP_FULL_DOOR_UNDER_SANITIZER();
  for (std::uint64_t seed : {51u, 52u}) {
    SCOPED_TRACE(seed);
    sim::scan::ScanOptions o;
    o.seed = seed;
    o.spacing = 0.0008;
    o.noise = 40e-6;
    o.defects = 12;
    o.outlier_fraction = 1e-5;
    o.shape.width = 0.8;
    o.shape.height = 0.6;
    const ScanRun r = run(o);
    EXPECT_EQ(r.eval.false_alarms, 0);
    ASSERT_FALSE(r.eval.classes.empty());
    EXPECT_EQ(r.eval.classes[0].found, r.eval.classes[0].total);  // 10 mm and 50 um or more
  }
}

TEST(Detect, OnACoarseScanALoneOutlierVertexIsNoBump) {
  // At 1.2 mm spacing a map pixel holds one or two samples, too few for the 3 x 3 median
  // spike test. An outlier vertex 2-20 mm off along its ray then stood as a 4 mm "bump"
  // 5 mm across. A defect lifts the vertices around its apex too (the paper's 9 mm bump
  // at 4.5 mm spacing: PapersCaseFindsTheTallBumpNotTheHandle); a thrown sample stands
  // alone.
  for (std::uint64_t seed : {29u, 30u}) {
    SCOPED_TRACE(seed);
    sim::scan::ScanOptions o = small_door(seed);
    o.spacing = 0.0012;
    const ScanRun clean = run(o);
    const ScanRun spiked = run(o, [seed](ingest::Mesh& mesh) {
      std::mt19937_64 rng(seed);
      std::uniform_real_distribution<float> u01(0.0f, 1.0f);
      for (int i = 0; i < 20; ++i) {
        auto& v =
            mesh.vertices[static_cast<std::size_t>(u01(rng) * static_cast<float>(mesh.vertices.size() - 1))];
        v += (u01(rng) < 0.5f ? -1.0f : 1.0f) * (0.002f + 0.018f * u01(rng)) *
             v.normalized();  // along the ray
      }
    });
    EXPECT_GE(clean.eval.matched, 2);  // the larger ones: the 5-6 mm are too fine for 1.2 mm
    EXPECT_EQ(spiked.eval.matched, clean.eval.matched);
    EXPECT_EQ(spiked.eval.false_alarms, 0);
  }
}

TEST(Detect, CleanPanelWithOutliersAndShuffledTrianglesHasNoDefects) {
  sim::scan::ScanOptions o = small_door(13);
  o.planted.clear();
  o.shape.window = true;
  o.shape.crease = true;
  o.outlier_fraction = 2e-4;
  o.dropouts = 5;
  o.shuffle = true;
  const ScanRun r = run(o);
  EXPECT_EQ(r.eval.reported, 0)
      << "first at "
      << (r.det.defects.empty() ? Eigen::Vector3d::Zero() : r.det.defects[0].defect.position).transpose();
  // The handle and the crease are there, as design features: their points fall on pixels
  // of design-feature findings (with the window and the borders these may be one finding,
  // now that the reference passes under the handle instead of bulging around it).
  const sim::scan::SynthScan scan = sim::scan::synthesize_scan(o);
  int checked = 0;
  for (const auto& feature : scan.features) {
    if (feature.name != "handle" && feature.name != "crease") continue;
    ++checked;
    int on_map = 0, on_design = 0;
    for (const auto& p : feature.points) {
      const Eigen::Vector3d q = r.det.map.to_map(p);
      const long k = r.det.map.pixel_of(q.x(), q.y());
      if (k < 0) continue;
      ++on_map;
      const int label = r.det.labels[static_cast<std::size_t>(k)];
      on_design += detect::is_feature_label(label) &&
                   r.det.features[detect::feature_index(label)].defect.defect_class ==
                       protocol::DefectClass::kDesignFeature;
    }
    EXPECT_GE(on_map, 5) << feature.name;
    EXPECT_GE(on_design, 0.8 * on_map) << feature.name;
  }
  EXPECT_EQ(checked, 2);
}

TEST(Detect, AnOutlierBehindTheSkinIsNoHole) {
  // A plane 0.85 m off, tilted 8 degrees, sampled every 0.31 mm on the sensor's raster
  // with 10 um noise; 1 point in 100 thrown 2-20 mm behind it along its ray. Each,
  // meshed to its neighbours, is a needle along its ray whose leaves, traced back, went
  // through the pixels its fan left empty in the skin: 3 of them were "holes" 1.6 mm
  // across (the other generator's SW36: 1 in 500 outliers, one such hole). No surface is
  // seen edge-on: those leaves are no evidence.
  ingest::Mesh mesh;
  std::mt19937_64 rng(11);
  std::normal_distribution<double> noise(0.0, 1e-5);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const int n = 400;
  const double step = 0.00031;
  const Eigen::Vector3d normal(std::sin(0.14), 0.0, -std::cos(0.14));  // towards the sensor
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      const Eigen::Vector3d ray =
          Eigen::Vector3d(step * (c - n / 2) / 0.85, step * (r - n / 2) / 0.85, 1.0).normalized();
      // where the ray meets the plane through (0, 0, 0.85)
      double range = (normal.dot(Eigen::Vector3d(0, 0, 0.85))) / normal.dot(ray) + noise(rng);
      if (u01(rng) < 1e-2) range += 0.002 + 0.018 * u01(rng);
      mesh.vertices.push_back((range * ray).cast<float>());
    }
  add_grid_triangles(mesh, n, n);
  const detect::Detection det = detect::detect(mesh, detect::DetectConfig{});
  for (const auto& f : det.defects)
    ADD_FAILURE() << report::class_name(f.defect.defect_class) << " " << 1e3 * f.defect.diameter << " mm at "
                  << f.defect.position.transpose();
}

TEST(Detect, ClustersOfOutliersAreNoBumps) {
  SKIP_FULL_DOOR_UNDER_SANITIZER();
  // A full door at 0.7 mm with 3 outliers in 1000. Some fall close together (here two
  // neighbours 7 and 2 mm towards the sensor, a third 2.5 mm away 2 mm off): their
  // triangles' normals made a group of octree leaves that the deviation test did not
  // confirm, and the trace their steep sides left on the smoothed map read as a bump of
  // 35 um (1 false alarm).
  sim::scan::ScanOptions o;
  o.seed = 7;
  o.spacing = 0.0007;
  o.outlier_fraction = 3e-3;
  const ScanRun r = run(o);
  EXPECT_EQ(r.eval.false_alarms, 0);
  EXPECT_EQ(r.eval.matched, r.eval.truth);
}

}  // namespace
}  // namespace dentmark
