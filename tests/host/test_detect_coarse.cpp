// End to end on coarse scans (4-6 mm between samples, 0.3 mm of noise: the paper's own
// density, a door of ~30 000 points): the paper's 9 mm wide, 11 mm high bump is found
// from the vertices (coarse_defects.h), the handle is never reported, and flying pixels
// are not taken for defects.
#include <gtest/gtest.h>

#include <random>

#include "detect_scans.h"

namespace dentmark {
namespace {

using namespace detect_test;

// The whole door with its handle, crease and window, and only the paper's bump (§V).
sim::scan::ScanOptions papers_door(double spacing) {
  sim::scan::ScanOptions o;
  o.seed = 3;
  o.spacing = spacing;
  o.noise = 3e-4;
  o.defects = 0;
  o.planted = {{{0.30 * o.shape.width, 0.275 * o.shape.height}, 0.009, 0.011}};
  return o;
}

// No reported defect within 'reach' of a point of the truth's handle.
void expect_handle_not_reported(const ScanRun& r, const sim::scan::ScanOptions& o, double reach) {
  const sim::scan::SynthScan scan = sim::scan::synthesize_scan(o);
  int handles = 0;
  for (const auto& feature : scan.features) {
    if (feature.name != "handle") continue;
    ++handles;
    for (const auto& f : r.det.defects)
      for (const auto& p : feature.points)
        ASSERT_GT((f.defect.position - p).norm(), reach) << "a defect on the handle at " << p.transpose();
  }
  EXPECT_EQ(handles, 1);
}

TEST(DetectCoarse, ThePapersBumpIsFoundWithin5mmAndTheHandleIsNot) {
  // At 4 to 5.5 mm the bump lifts two vertices or more over the noise. (At 6 mm on this
  // door it stands on one: docs/detection.md §12.)
  for (const double spacing : {0.004, 0.005, 0.0055}) {
    SCOPED_TRACE(spacing);
    const sim::scan::ScanOptions o = papers_door(spacing);
    const ScanRun r = run(o);
    expect_only_the_papers_bump(r);
    if (r.det.defects.size() != 1u) continue;  // (reported above)
    // The height is the highest sample's: over the detection threshold (5.5 σ), and no
    // higher than the apex plus 4 σ of noise (a sample 2 mm off the apex reads 7 mm).
    EXPECT_GT(r.det.defects[0].defect.height, 5.5 * o.noise);
    EXPECT_LT(r.det.defects[0].defect.height, 0.011 + 4.0 * o.noise);
    expect_handle_not_reported(r, o, 0.02);
  }
}

TEST(DetectCoarse, FlyingPixelsAreNoDefects) {
  // Thirty samples thrown 2-20 mm along their own ray, either way: each stands alone
  // among neighbours on the surface, and none is reported; the bump still is.
  const sim::scan::ScanOptions o = papers_door(0.005);
  const ScanRun r = run(o, [](ingest::Mesh& mesh) {
    std::mt19937_64 rng(35);
    std::uniform_real_distribution<float> u01(0.0f, 1.0f);
    for (int i = 0; i < 30; ++i) {
      auto& v =
          mesh.vertices[static_cast<std::size_t>(u01(rng) * static_cast<float>(mesh.vertices.size() - 1))];
      v += (u01(rng) < 0.5f ? -1.0f : 1.0f) * (0.002f + 0.018f * u01(rng)) * v.normalized();
    }
  });
  EXPECT_EQ(r.eval.matched, 1);
  EXPECT_EQ(r.eval.false_alarms, 0);
}

}  // namespace
}  // namespace dentmark
