// End to end on synthetic scans with ground truth: dents and bumps found where they
// are, with their depth; design features and outliers never reported.
#include <gtest/gtest.h>
#include <omp.h>

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

namespace dentmark {
namespace {

// Full 1.0 x 0.8 m doors take a few seconds here and many minutes in a Debug build under
// AddressSanitizer; the smaller scans of the other tests run the same code there.
#if defined(__SANITIZE_ADDRESS__)
#define SKIP_FULL_DOOR_UNDER_SANITIZER() GTEST_SKIP() << "full-door scan: run by the native preset"
constexpr bool kSanitized = true;  // (a small door takes ~2 minutes there)
#else
#define SKIP_FULL_DOOR_UNDER_SANITIZER() (void)0
constexpr bool kSanitized = false;
#endif

struct ScanRun {
  report::Evaluation eval;
  detect::Detection det;
};

// `more` adds to the scan what the scanner saw besides the panel.
ScanRun run(const sim::scan::ScanOptions& o, const std::function<void(ingest::Mesh&)>& more = {}) {
  sim::scan::SynthScan scan = sim::scan::synthesize_scan(o);
  ingest::Mesh mesh;
  mesh.vertices = scan.vertices;
  mesh.triangles = scan.triangles;
  if (more) more(mesh);
  ScanRun r;
  r.det = detect::detect(mesh, detect::DetectConfig{});
  const report::TruthFile truth = report::truth_from_scan(scan);
  report::DefectsFile found;
  for (const auto& f : r.det.defects)
    found.defects.push_back({report::class_name(f.defect.defect_class), f.defect});
  r.eval = report::evaluate(truth, found);
  return r;
}

// A small door (0.5 x 0.4 m) at 0.5 mm / 20 µm with defects at the target limits.
sim::scan::ScanOptions small_door(std::uint64_t seed) {
  sim::scan::ScanOptions o;
  o.seed = seed;
  o.shape.width = 0.5;
  o.shape.height = 0.4;
  o.defects = 0;
  o.shape.window = false;  // room for the defects; the clean-panel test keeps every feature
  o.shape.crease = false;
  o.planted = {{{0.10, 0.08}, 0.010, -5e-5},
               {{0.22, 0.08}, 0.012, 5e-5},
               {{0.36, 0.10}, 0.005, -1e-4},
               {{0.10, 0.23}, 0.006, 1e-4},
               {{0.20, 0.31}, 0.020, -3e-4}};
  return o;
}

TEST(Detect, FindsTargetSizedDefectsWithPositionAndDepth) {
  int depth_ok = 0;
  for (std::uint64_t seed : {11u, 12u}) {
    SCOPED_TRACE(seed);
    const ScanRun r = run(small_door(seed));
    EXPECT_EQ(r.eval.matched, 5);
    EXPECT_EQ(r.eval.false_alarms, 0);
    EXPECT_LE(r.eval.max_position_error, 0.001);
    // Depth (along the normal) within 15 µm, and nearly always within max(10 µm, 10 %)
    // (the fit's noise is ~7 µm on a 0.1 mm dent at 20 µm scanner noise).
    depth_ok += r.eval.depth_within_tolerance;
    EXPECT_LE(r.eval.max_depth_error, 15e-6);
    // Every defect's normal agrees with the panel's within 5 degrees.
    for (const auto& f : r.det.defects)
      EXPECT_GT(f.defect.normal.dot(r.det.map.axes.row(2).transpose()), 0.9);
  }
  EXPECT_GE(depth_ok, 9);
}

TEST(Detect, DefectsBesideARolledBorderAreNotTakenForIt) {
  // Dents and bumps 18 mm from a panel's edge rolled at 6 mm (their rims 8-13 mm from
  // it): the edge's candidate is a design feature, and everything within 8 mm of one was
  // too, so 0 of 10 were found (the same at 16 mm; 8 of 10 at 20 mm). A border's band is
  // the roll-off, not a feature with shoulders: beyond 2 mm of it the panel is its own.
  int found = 0, planted = 0;
  for (std::uint64_t seed : {21u, 22u}) {
    if (kSanitized && seed != 21u) continue;
    sim::scan::ScanOptions o;
    o.seed = seed;
    o.shape.width = 0.5, o.shape.height = 0.4;
    o.shape.window = false, o.shape.crease = false, o.shape.handle = false;
    o.defects = 0;
    const double d = 0.018, dia = seed == 21u ? 0.010 : 0.006;
    o.planted = {{{d, 0.10}, dia, -1e-4},
                 {{0.5 - d, 0.14}, dia, 1e-4},
                 {{0.18, d}, dia, 1e-4},
                 {{0.30, 0.4 - d}, dia, -1e-4},
                 {{d, 0.30}, 0.015, 2e-4}};
    const ScanRun r = run(o);
    SCOPED_TRACE(seed);
    EXPECT_EQ(r.eval.false_alarms, 0);
    EXPECT_LE(r.eval.max_position_error, 0.001);
    found += r.eval.matched, planted += static_cast<int>(o.planted.size());
  }
  EXPECT_GE(found, planted * 7 / 10);
}

TEST(Detect, ACreaseThatRunsIntoTheBorderKeepsItsShoulders) {
  SKIP_FULL_DOOR_UNDER_SANITIZER();
  // The crease joins the border's candidate where it meets the edge; with the border's
  // surroundings narrowed to 2 mm, a piece of its shoulder 270 mm from the edge was
  // reported as a 55 um dent (BM_QualityOverSeeds/20/1's seed 17). Only the band along
  // the border is the border's.
  sim::scan::ScanOptions o;
  o.seed = 1017;
  o.defects = 12;
  o.min_diameter = 0.005;
  o.min_depth = 5e-5;
  o.dropouts = 2;
  o.holes = 2;
  const ScanRun r = run(o);
  EXPECT_EQ(r.eval.false_alarms, 0);
  EXPECT_EQ(r.eval.matched, r.eval.truth);
}

TEST(Detect, TrianglesWoundEitherWayGiveTheSameFindings) {
  // A mesh merged from several views, or written by a tool that does not keep winding:
  // neighbours wound opposite ways cancelled in the octree's normal sums, and parts wound
  // the other way read as a surface turned round, their dents as bumps (before: 3 and 4
  // of 10 found on a full door rewound in halves and at random, 6 and 7 of the wrong
  // kind; the same with the half on vertices of its own, as a second view). Such a mesh
  // is rewound consistently first; one wound the other way throughout is consistent, and
  // left as it is.
  using Which = std::function<bool(const ingest::Mesh&, const std::array<std::uint32_t, 3>&, std::size_t)>;
  const auto rewind_if = [](const Which& which, bool own_vertices = false) {
    return [which, own_vertices](ingest::Mesh& mesh) {
      const std::size_t shared = mesh.vertices.size();
      std::vector<std::uint32_t> copy(shared, 0);
      for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
        auto& t = mesh.triangles[i];
        if (!which(mesh, t, i)) continue;
        std::swap(t[1], t[2]);
        if (own_vertices)
          for (auto& v : t)
            if (v < shared) {
              if (copy[v] == 0) {
                copy[v] = static_cast<std::uint32_t>(mesh.vertices.size());
                mesh.vertices.push_back(mesh.vertices[v]);
              }
              v = copy[v];
            }
      }
    };
  };
  const Which every = [](const ingest::Mesh&, const std::array<std::uint32_t, 3>&, std::size_t) {
    return true;
  };
  const Which at_random = [](const ingest::Mesh&, const std::array<std::uint32_t, 3>&, std::size_t i) {
    return (i * 2654435761u >> 7) % 2 == 0;
  };
  const Which right_half = [](const ingest::Mesh& m, const std::array<std::uint32_t, 3>& t, std::size_t) {
    return m.vertices[t[0]].x() > 0.0f;
  };
  const Which a_patch = [](const ingest::Mesh& m, const std::array<std::uint32_t, 3>& t, std::size_t) {
    const Eigen::Vector3f& p = m.vertices[t[0]];
    return std::abs(p.x() + 0.15f) < 0.04f && std::abs(p.y() + 0.12f) < 0.04f;
  };
  struct Case {
    const char* name;
    std::function<void(ingest::Mesh&)> change;
    bool rewound;
  };
  const std::vector<Case> cases{Case{"at random", rewind_if(at_random), true},
                                Case{"right half, a view of its own", rewind_if(right_half, true), true},
                                Case{"as scanned", {}, false},
                                Case{"all the other way", rewind_if(every), false},
                                Case{"right half", rewind_if(right_half), true},
                                Case{"a patch", rewind_if(a_patch), true}};
  // Under a sanitizer the two that walk the triangles and match the parts.
  for (std::size_t k = 0; k < (kSanitized ? 2 : cases.size()); ++k) {
    const Case& c = cases[k];
    SCOPED_TRACE(c.name);
    const ScanRun r = run(small_door(17), c.change);
    EXPECT_EQ(r.eval.matched, 5);
    EXPECT_EQ(r.eval.false_alarms, 0);
    EXPECT_EQ(r.eval.wrong_sign, 0);
    EXPECT_EQ(r.det.stats.charts, 1u);
    EXPECT_EQ(r.det.stats.rewound_triangles > 0, c.rewound) << r.det.stats.rewound_triangles;
    EXPECT_LE(r.eval.max_position_error, 0.001);
  }
}

TEST(Detect, AScanInAFrameWhoseOriginIsInsideTheBodyKeepsDentsAsDents) {
  // The same door in a vehicle's or a part's frame: turned half round about a vertical
  // axis 0.5 m behind the panel, so that the origin lies 1 m behind it, on the side its
  // triangles face away from. Taken for a sensor there, it looked at the panel from the
  // inside, and every dent read as a bump (5 of 5). The panel bulges outwards: that
  // decides when the origin and the triangles disagree. A sensor-frame mesh wound the
  // other way throughout (the origin right, the triangles not) stays as it was.
  sim::scan::SynthScan scan = sim::scan::synthesize_scan(small_door(19));
  double depth = 0.0;
  for (const auto& v : scan.vertices) depth += v.z();
  const double c = depth / static_cast<double>(scan.vertices.size()) + 0.5;
  const auto turn = [c](const Eigen::Vector3d& p) { return Eigen::Vector3d(-p.x(), p.y(), 2.0 * c - p.z()); };
  for (const bool turned : {true, false})
    for (const bool rewound : {false, true}) {
      if (kSanitized && !(turned && !rewound)) continue;  // (there, the case it is about)
      SCOPED_TRACE(std::string(turned ? "turned" : "sensor frame") + (rewound ? ", rewound" : ""));
      ingest::Mesh mesh;
      mesh.vertices = scan.vertices;
      mesh.triangles = scan.triangles;
      report::TruthFile truth = report::truth_from_scan(scan);
      if (turned) {
        for (auto& v : mesh.vertices) v = turn(v.cast<double>()).cast<float>();
        for (auto& d : truth.defects) {
          d.defect.position = turn(d.defect.position);
          d.defect.normal = Eigen::Vector3d(-d.defect.normal.x(), d.defect.normal.y(), -d.defect.normal.z());
        }
        for (auto& f : truth.features)
          for (auto& p : f.points) p = turn(p);
      }
      if (rewound)
        for (auto& t : mesh.triangles) std::swap(t[1], t[2]);
      const detect::Detection det = detect::detect(mesh, detect::DetectConfig{});
      report::DefectsFile found;
      for (const auto& f : det.defects)
        found.defects.push_back({report::class_name(f.defect.defect_class), f.defect});
      const report::Evaluation eval = report::evaluate(truth, found);
      // A turned scan wound the other way is a sensor's view of the panel's inside (the
      // triangles face the origin): there the origin is believed, and its dents are bumps.
      const bool inside = turned && rewound;
      EXPECT_EQ(eval.matched, inside ? 0 : 5);
      EXPECT_EQ(eval.wrong_sign, inside ? 5 : 0);
      EXPECT_EQ(eval.false_alarms - eval.wrong_sign, 0);
      EXPECT_LE(eval.max_position_error, 0.001);
    }
}

TEST(Detect, MeshedOutlierSpikesNeitherHideNorFakeDefects) {
  // A mesher without an edge-length filter keeps an outlier's triangles: a spike of
  // 2-20 mm on one vertex, its six triangles 50-400 times a normal one's area. About one
  // spike per 3 cm² here. The 3 x 3 median hides them from the candidates; unless they
  // are also kept out of the reference fits, each pulls its window's reference by
  // ~0.1 mm; one behind the skin must not pass for a through-hole, one inside a defect
  // must not become its peak, one in a defect's ring must not make it "not a smooth
  // panel". (Before: 1 to 3 of the 5 defects lost on 9 of 20 seeds, and false holes.)
  for (std::uint64_t seed : {29u, 30u}) {
    SCOPED_TRACE(seed);
    sim::scan::SynthScan scan = sim::scan::synthesize_scan(small_door(seed));
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> u01(0.0f, 1.0f);
    int spikes = 0;
    for (auto& v : scan.vertices)
      if (u01(rng) < 3e-4f) {
        const float off = (u01(rng) < 0.5f ? -1.0f : 1.0f) * (0.002f + 0.018f * u01(rng));
        v += off * v.normalized();  // along the sensor's ray
        ++spikes;
      }
    ASSERT_GT(spikes, 150);
    ingest::Mesh mesh;
    mesh.vertices = scan.vertices;
    mesh.triangles = scan.triangles;
    const detect::Detection det = detect::detect(mesh, detect::DetectConfig{});
    report::DefectsFile found;
    for (const auto& f : det.defects)
      found.defects.push_back({report::class_name(f.defect.defect_class), f.defect});
    const report::Evaluation eval = report::evaluate(report::truth_from_scan(scan), found);
    EXPECT_EQ(eval.matched, 5);
    EXPECT_EQ(eval.false_alarms, 0);
    EXPECT_LE(eval.max_position_error, 0.001);
    // As without spikes, up to the fit's noise on the 5 mm, 0.1 mm dent (the worst of 20
    // seeds was 23 µm).
    EXPECT_LE(eval.max_depth_error, 25e-6);
    EXPECT_LE(eval.mean_depth_error, 10e-6);
    for (const auto& f : det.defects) EXPECT_GT(f.defect.normal.dot(det.map.axes.row(2).transpose()), 0.9);
  }
}

TEST(Detect, TheSameScanGivesTheSameFindingsToTheLastBit) {
  // A station's reports must be reproducible: the vertex samples under a candidate were
  // once merged in whatever order the threads finished, which moved a height in its
  // 16th digit from one run to the next.
  sim::scan::SynthScan scan = sim::scan::synthesize_scan(small_door(13));
  ingest::Mesh mesh;
  mesh.vertices = scan.vertices;
  mesh.triangles = scan.triangles;
  const detect::Detection first = detect::detect(mesh, detect::DetectConfig{});
  ASSERT_EQ(first.defects.size(), 5u);
  const auto expect_same_findings = [&first](const detect::Detection& again) {
    ASSERT_EQ(again.defects.size(), first.defects.size());
    for (std::size_t i = 0; i < first.defects.size(); ++i) {
      const auto &a = first.defects[i].defect, &b = again.defects[i].defect;
      EXPECT_EQ(a.position, b.position);
      EXPECT_EQ(a.normal, b.normal);
      EXPECT_EQ(a.height, b.height);
      EXPECT_EQ(a.diameter, b.diameter);
    }
  };
  for (int run = 0; run < 8; ++run) expect_same_findings(detect::detect(mesh, detect::DetectConfig{}));
  // And whatever the number of threads: the octree's slices, the map's bands and every
  // other split are summed in a fixed order.
  const int initial = omp_get_max_threads();
  for (const int threads : {1, 3}) {
    SCOPED_TRACE(threads);
    omp_set_num_threads(threads);
    expect_same_findings(detect::detect(mesh, detect::DetectConfig{}));
  }
  omp_set_num_threads(initial);
}

TEST(Detect, ThroughHolesAreHolesAndDropoutsAreNot) {
  // Holes show the inner structure 60 mm behind the skin; dropouts show nothing. Both are
  // empty discs on the skin of similar size; only the holes may be reported.
  for (std::uint64_t seed : {21u, 22u}) {
    SCOPED_TRACE(seed);
    sim::scan::ScanOptions o = small_door(seed);
    o.planted.resize(2);
    o.holes = 3;
    o.dropouts = 4;
    o.outlier_fraction = 1e-4;
    const ScanRun r = run(o);
    EXPECT_EQ(r.eval.classes[2].total, 3);
    EXPECT_EQ(r.eval.classes[2].found, 3);
    EXPECT_EQ(r.eval.matched, 5);
    EXPECT_EQ(r.eval.false_alarms, 0);
    EXPECT_EQ(r.eval.wrong_sign, 0);
    EXPECT_LE(r.eval.max_position_error, 0.001);
    int holes = 0;
    for (const auto& f : r.det.defects)
      if (f.defect.defect_class == protocol::DefectClass::kHole) {
        ++holes;
        EXPECT_GT(f.defect.normal.dot(r.det.map.axes.row(2).transpose()), 0.9);
      }
    EXPECT_EQ(holes, 3);
  }
}

TEST(Detect, FullDoorsWithHolesNextToTheCreaseHaveNoMissesAndNoFalseAlarms) {
  SKIP_FULL_DOOR_UNDER_SANITIZER();
  // Two full doors that once failed: on 1010 three dents whose edges reached into the
  // crease's wide deviation band were absorbed as 'next to a design feature'; on 1020 the
  // far wall seen through two holes pulled the local reference of the skin around them
  // 1-2 mm down, three false bumps 70-130 mm across.
  for (std::uint64_t seed : {1010u, 1020u}) {
    SCOPED_TRACE(seed);
    sim::scan::ScanOptions o;
    o.seed = seed;
    o.defects = 12;
    o.min_diameter = 0.005;
    o.min_depth = 5e-5;
    o.outlier_fraction = 1e-4;
    o.dropouts = static_cast<int>((seed - 1000) % 3);
    o.holes = static_cast<int>((seed - 1000) % 3);
    o.shuffle = true;
    const ScanRun r = run(o);
    EXPECT_EQ(r.eval.matched, r.eval.truth);
    EXPECT_EQ(r.eval.false_alarms, 0);
    EXPECT_EQ(r.eval.on_features, 0);
  }
}

TEST(Detect, CoarseNoisyScanMeasuresTheApexByAFitNotTheNoisiestVertex) {
  // 1 mm spacing and 30 µm noise: a pixel holds one or two samples. The apex of a defect
  // wider than five samples comes from the fit over its vertices; the single most extreme
  // vertex would read 2-3 sigma (60-90 µm) too deep and up to 3.5 mm off its centre.
  for (std::uint64_t seed : {41u, 42u}) {
    SCOPED_TRACE(seed);
    sim::scan::ScanOptions o = small_door(seed);
    o.spacing = 0.001;
    o.noise = 3e-5;
    o.planted = {{{0.12, 0.10}, 0.020, -3e-4}, {{0.30, 0.12}, 0.016, 2e-4}, {{0.20, 0.28}, 0.024, -1.5e-4}};
    const ScanRun r = run(o);
    EXPECT_EQ(r.eval.matched, 3);
    EXPECT_EQ(r.eval.false_alarms, 0);
    EXPECT_LE(r.eval.max_position_error, 0.001);
    EXPECT_LE(r.eval.max_depth_error, 30e-6);
    EXPECT_LE(r.eval.mean_depth_error, 15e-6);
  }
}

TEST(Detect, NoiseFreeScanFindsEveryDefect) {
  // A mesh made from CAD or by a simulator has no noise: the deviation's noise is float
  // rounding (0.04 um), and the ring about a defect is rarely that smooth. By the
  // rough-ring test such a defect was "between features": a 100 mm patch, 0.8 m from
  // the sensor, with one 16 mm, 0.2 mm deep dent found nothing.
  ingest::Mesh patch;
  const int n = 201;
  const double spacing = 0.0005, width = 0.016, depth = 2e-4;
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      const double x = c * spacing, y = r * spacing, d = std::hypot(x - 0.05, y - 0.05);
      const double dent = d < 0.5 * width ? depth * std::pow(std::cos(std::numbers::pi * d / width), 2) : 0.0;
      patch.vertices.emplace_back(x, y, 0.8 + dent);  // deeper: away from the sensor at the origin
    }
  for (std::uint32_t r = 0; r + 1 < n; ++r)
    for (std::uint32_t c = 0; c + 1 < n; ++c) {
      const std::uint32_t k = r * n + c;
      patch.triangles.push_back({k, k + 1, k + n});
      patch.triangles.push_back({k + 1, k + n + 1, k + n});
    }
  const detect::Detection det = detect::detect(patch, detect::DetectConfig{});
  EXPECT_LT(det.stats.deviation_noise, 1e-6);
  ASSERT_EQ(det.defects.size(), 1u);
  const protocol::Defect& d = det.defects[0].defect;
  EXPECT_EQ(d.defect_class, protocol::DefectClass::kDent);
  EXPECT_NEAR(d.height, -depth, 5e-6);
  EXPECT_LT((d.position - Eigen::Vector3d(0.05, 0.05, 0.8 + depth)).norm(), 5e-4);

  // And a door with its features, defects planted among the drawn ones.
  sim::scan::ScanOptions o = small_door(5);
  o.noise = 0.0;
  o.planted.push_back({{0.36, 0.28}, 0.024, -4.4e-4});
  o.planted.push_back({{0.15, 0.16}, 0.017, 6e-5, 0.25});  // its trough is in its ring
  const ScanRun r = run(o);
  EXPECT_EQ(r.eval.matched, 7);
  EXPECT_EQ(r.eval.false_alarms, 0);
  // (The rimmed bump is measured from its trough, 13 um below the panel; the rest
  // within 1 um.)
  EXPECT_LE(r.eval.max_depth_error, 15e-6);
  EXPECT_GE(r.eval.depth_within_tolerance, 6);
}

TEST(Detect, ADentsRimIsPartOfTheDent) {
  // A dent pushes the metal around it up into a low ring (a bump has a trough around
  // it). The ring came out as a second defect of the opposite kind, wider and centred
  // on the first: here a 31 mm "dent" 31 um deep around a 12 mm bump.
  sim::scan::ScanOptions o = small_door(21);
  for (auto& d : o.planted) d.rim = 0.3, d.height *= 3.0;
  o.planted.push_back({{0.15, 0.16}, 0.024, -4e-4, 0.3});
  const ScanRun r = run(o);
  EXPECT_EQ(r.eval.matched, 6);
  EXPECT_EQ(r.eval.false_alarms, 0);
  EXPECT_EQ(r.eval.wrong_sign, 0);
  EXPECT_LE(r.eval.max_position_error, 0.001);
  EXPECT_LE(r.eval.max_depth_error, 30e-6);
}

TEST(Detect, AProfilersHeightsReadUpAsOutside) {
  // A laser profiler writes heights over its travel (x across the line, y along the
  // travel, z up towards it) from an origin near the panel, not in front of it: the
  // view is orthographic and outside is where the meshed triangles face. The origin a
  // few millimetres below the panel's plane was taken for the sensor (the dent read as a
  // bump), and the mesher's faces pointed whichever way the eigen solver's axis did.
  for (const double tilt : {0.0, 0.3})
    for (const int order : {0, 1, 2, 3}) {
      ingest::Mesh cloud;
      const double step = 0.0005;
      for (int rr = 0; rr < 500; ++rr)
        for (int cc = 0; cc < 300; ++cc) {
          const int r = order & 1 ? 499 - rr : rr, c = order & 2 ? 299 - cc : cc;
          const double x = (c - 150) * step, y = r * step;
          const double d = std::hypot(x - 0.01, y - 0.12);
          double z = 0.005 + tilt * x - 0.2 * (x * x + (y - 0.16) * (y - 0.16));
          if (d < 0.008) z -= 2e-4 * std::pow(std::cos(std::numbers::pi * d / 0.016), 2);
          cloud.vertices.emplace_back(x, y, z);
        }
      ingest::mesh_point_cloud(cloud);
      const detect::Detection det = detect::detect(cloud, detect::DetectConfig{});
      ASSERT_EQ(det.defects.size(), 1u) << "tilt " << tilt << ", order " << order;
      EXPECT_EQ(det.defects[0].defect.defect_class, protocol::DefectClass::kDent)
          << "tilt " << tilt << ", order " << order;
      EXPECT_NEAR(det.defects[0].defect.height, -2e-4, 2e-5) << "tilt " << tilt << ", order " << order;
    }
}

TEST(Detect, VerticesSeenPastThePanelDoNotSetADefectsDepth) {
  // Between a panel's samples the scanner sees what lies behind it (a wall, a rack), and
  // those vertices fall in the panel's pixels, most on a coarse scan. A defect's depth is
  // fitted to the vertices under it: a wall's vertex made a "dent" 445 mm deep. Here a
  // coarse door has unused vertices 0.5 m behind half of its own: they made a false
  // alarm and cost a defect.
  sim::scan::ScanOptions o = small_door(4);
  o.spacing = 0.0011;  // 2.2 mm pixels
  const ScanRun r = run(o, [](ingest::Mesh& mesh) {
    const std::vector<Eigen::Vector3f> panel = mesh.vertices;
    for (std::size_t i = 0; i < panel.size(); i += 2)
      mesh.vertices.push_back(panel[i] + 0.5f * panel[i].normalized());  // along the sensor's ray
  });
  EXPECT_GE(r.eval.matched, 3);  // (the 5 and 6 mm defects are below a 2.2 mm pixel's reach)
  EXPECT_EQ(r.eval.false_alarms, 0);
  for (const auto& f : r.det.defects) EXPECT_LT(std::abs(f.defect.height), 0.005);
}

// Two triangles per cell of a rows x cols grid of vertices stored row by row.
void add_grid_triangles(ingest::Mesh& mesh, int rows, int cols) {
  for (int r = 0; r + 1 < rows; ++r)
    for (int c = 0; c + 1 < cols; ++c) {
      const auto k = [&](int dr, int dc) { return static_cast<std::uint32_t>((r + dr) * cols + c + dc); };
      mesh.triangles.push_back({k(0, 0), k(1, 0), k(0, 1)});
      mesh.triangles.push_back({k(0, 1), k(1, 0), k(1, 1)});
    }
}

// Two triangles per cell of an n x n grid of samples `step` apart whose four corners were
// seen (index: the vertex of each grid point, -1 where unseen). Returns their area.
double add_seen_grid_triangles(ingest::Mesh& mesh, const std::vector<std::int64_t>& index, int n,
                               double step) {
  double area = 0.0;
  for (int r = 0; r + 1 < n; ++r)
    for (int c = 0; c + 1 < n; ++c) {
      const auto at = [&](int dr, int dc) { return index[static_cast<std::size_t>((r + dr) * n + c + dc)]; };
      if (at(0, 0) < 0 || at(0, 1) < 0 || at(1, 0) < 0 || at(1, 1) < 0) continue;
      const auto k = [&](int dr, int dc) { return static_cast<std::uint32_t>(at(dr, dc)); };
      mesh.triangles.push_back({k(0, 0), k(1, 0), k(0, 1)});
      mesh.triangles.push_back({k(0, 1), k(1, 0), k(1, 1)});
      area += step * step;
    }
  return area;
}

// Adds a wall at depth z (the panel's centre is at 0.9 m; on a slope for a floor), n x n
// samples 1.5 mm apart with 20 um noise, as a scanner whose view is larger than the panel
// records it; the panel's shadow on it (its vertices along their rays, as a box) is not
// seen. Returns the wall's area.
double add_wall_behind(ingest::Mesh& mesh, bool floor, int n, double z = 1.5) {
  const auto z_at = [&](double x, double y) { return z + (floor ? 0.4 * y + 0.2 * x : 0.0); };
  Eigen::AlignedBox2d shadow;
  for (const Eigen::Vector3f& v : mesh.vertices) {
    const Eigen::Vector2d ray = v.head<2>().cast<double>() / v.z();
    shadow.extend(ray * z_at(0.0, 0.0));
  }
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, 2e-5);
  const double step = 0.0015;
  const Eigen::Vector2d centre = shadow.center();
  std::vector<std::int64_t> index(static_cast<std::size_t>(n * n), -1);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      const Eigen::Vector2d p = centre + step * Eigen::Vector2d(c - n / 2, r - n / 2);
      if (shadow.exteriorDistance(p) < 0.01) continue;
      index[static_cast<std::size_t>(r * n + c)] = static_cast<std::int64_t>(mesh.vertices.size());
      mesh.vertices.emplace_back(p.x(), p.y(), z_at(p.x(), p.y()) + noise(rng));
    }
  return add_seen_grid_triangles(mesh, index, n, step);
}

// A cols x rows grid of samples 'spacing' apart, 0.8 m before the sensor plus
// height(x, y) (away from it) and 15 µm of noise, meshed.
ingest::Mesh noisy_patch(int cols, int rows, double spacing,
                         const std::function<double(double, double)>& height, std::uint64_t seed) {
  ingest::Mesh patch;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 1.5e-5);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const double x = c * spacing, y = r * spacing;
      patch.vertices.emplace_back(x, y, 0.8 + height(x, y) + noise(rng));
    }
  add_grid_triangles(patch, rows, cols);
  return patch;
}

TEST(Detect, ACreaseShapedDentIsReadToItsFloor) {
  // A long narrow dent (a crease from a sharp edge: 40 x 6 mm, cos² across, flat along
  // with cos² ends) and the same as a bump, at 0.4 mm and 15 µm. Their apex was fitted
  // over a disc of the half-height area's radius, 6 mm, twice the trough's half-height
  // width: it reached the panel on both sides and read 0.2 mm as 0.15 (another
  // generator's roofs, 22-28 % short, 0 of 7 within tolerance).
  struct Crease {
    Eigen::Vector2d centre;
    double angle, height;
  };
  const Crease creases[] = {{{0.04, 0.05}, 0.5, -2e-4}, {{0.12, 0.05}, 2.0, 2e-4}};
  const auto crease_at = [&](double x, double y) {
    double z = 0.0;
    for (const Crease& c : creases) {
      const Eigen::Vector2d d = Eigen::Rotation2Dd(-c.angle) * (Eigen::Vector2d(x, y) - c.centre);
      const double across =
          std::abs(d.y()) < 0.003 ? std::pow(std::cos(std::numbers::pi * d.y() / 0.006), 2) : 0.0;
      const double end = std::max(0.0, std::abs(d.x()) - 0.017);
      z += c.height * across * (end < 0.003 ? std::pow(std::cos(std::numbers::pi * end / 0.006), 2) : 0.0);
    }
    return z;
  };
  // A dent is deeper: away from the sensor at the origin.
  const ingest::Mesh patch = noisy_patch(
      401, 251, 0.0004, [&](double x, double y) { return -crease_at(x, y); }, 11);
  const detect::Detection det = detect::detect(patch, detect::DetectConfig{});
  ASSERT_EQ(det.defects.size(), 2u);
  for (const Crease& c : creases) {
    const auto found = std::find_if(det.defects.begin(), det.defects.end(), [&](const auto& f) {
      return (f.defect.position.template head<2>() - c.centre).norm() < 0.005;
    });
    ASSERT_NE(found, det.defects.end()) << "crease at angle " << c.angle;
    EXPECT_EQ(found->defect.defect_class,
              c.height < 0 ? protocol::DefectClass::kDent : protocol::DefectClass::kBump);
    EXPECT_NEAR(found->defect.height, c.height, 0.1 * std::abs(c.height)) << "crease at angle " << c.angle;
  }
}

TEST(Detect, DefectsBesideASharpFoldAreFoundAndTheFoldIsNot) {
  // A character line: a 0.2 rad fold rounded at 2 mm, at 30° across the map, 0.5 mm and
  // 15 µm, with dents and bumps 16-26 mm from it on both sides. Every window across the
  // fold left a band as wide as itself, which swallowed them (an independent generator's
  // hoods: 26 of 60 found); the fits from the windows beside each pixel leave only the
  // fold's line, a design feature.
  const Eigen::Vector2d along(std::cos(0.52), std::sin(0.52)), across(-along.y(), along.x());
  const Eigen::Vector2d centre(0.15, 0.10);
  struct Planted {
    double s, t, diameter, height;  // along and across the fold from the centre (m)
  };
  const Planted planted[] = {{-0.10, 0.016, 0.010, -1.5e-4}, {-0.06, -0.018, 0.012, 1e-4},
                             {-0.02, 0.020, 0.014, -8e-5},   {0.02, -0.022, 0.010, 2e-4},
                             {0.06, 0.024, 0.012, 1.2e-4},   {0.10, -0.026, 0.014, -1e-4}};
  const auto height_at = [&](double x, double y) {
    const Eigen::Vector2d p = Eigen::Vector2d(x, y) - centre;
    // A hyperbola: slopes of -0.1 and +0.1 either side, a 2 mm radius where they meet.
    double z = 0.1 * std::sqrt(std::pow(p.dot(across), 2) + 0.0002 * 0.0002);
    for (const Planted& d : planted) {
      const double r = (p - d.s * along - d.t * across).norm();
      if (r < 0.5 * d.diameter) z -= d.height * std::pow(std::cos(std::numbers::pi * r / d.diameter), 2);
    }
    return z;  // a bump is towards the sensor at the origin: less deep
  };
  const ingest::Mesh patch = noisy_patch(601, 401, 0.0005, height_at, 17);
  const detect::Detection det = detect::detect(patch, detect::DetectConfig{});
  EXPECT_EQ(det.defects.size(), std::size(planted));
  for (const Planted& d : planted) {
    const Eigen::Vector2d at = centre + d.s * along + d.t * across;
    const auto found = std::find_if(det.defects.begin(), det.defects.end(), [&](const auto& f) {
      return (f.defect.position.template head<2>() - at).norm() < 0.001;
    });
    ASSERT_NE(found, det.defects.end()) << "defect " << d.t * 1e3 << " mm from the fold";
    EXPECT_EQ(found->defect.defect_class,
              d.height < 0 ? protocol::DefectClass::kDent : protocol::DefectClass::kBump);
    EXPECT_NEAR(found->defect.height, d.height, std::max(1e-5, 0.1 * std::abs(d.height)));
  }
  // The fold itself is a design feature, never a defect.
  bool fold_seen = false;
  for (const auto& f : det.features)
    fold_seen = fold_seen || (f.defect.defect_class == protocol::DefectClass::kDesignFeature &&
                              std::abs((f.defect.position.template head<2>() - centre).dot(across)) < 0.004);
  EXPECT_TRUE(fold_seen);
}

TEST(Detect, AWallFarBehindThePanelIsLeftOut) {
  // The wall surrounded the panel on the map, a step of half a metre behind it, and
  // showed through every pixel the panel left empty: here 1 of the 5 defects was lost and
  // 98 false alarms made. It is left out now; so is a floor at an angle.
  for (const bool floor : {false, true}) {
    double wall_area = 0.0;
    const ScanRun r =
        run(small_door(3), [&](ingest::Mesh& mesh) { wall_area = add_wall_behind(mesh, floor, 800); });
    EXPECT_EQ(r.eval.matched, 5) << (floor ? "floor" : "wall");
    EXPECT_EQ(r.eval.false_alarms, 0) << (floor ? "floor" : "wall");
    EXPECT_GT(r.det.stats.background_area, 0.9 * wall_area) << (floor ? "floor" : "wall");
    EXPECT_LT(r.det.stats.background_area, 1.2 * wall_area) << (floor ? "floor" : "wall");
  }
}

// Adds a wall at height z_at(x, y), half x half metres round the sensor's axis with
// samples `step` apart and 20 um noise, seen right up to the panel's silhouette (hidden
// only where a panel's vertex lies on the ray within 4 mm). Returns the wall's area.
double add_wall_to_the_silhouette(ingest::Mesh& mesh, const std::function<double(double, double)>& z_at,
                                  double step, double half) {
  const double cell = 0.002;  // of the panel's shadow, in x / z and y / z
  std::set<std::pair<int, int>> shadow;
  for (const Eigen::Vector3f& v : mesh.vertices)
    shadow.insert({static_cast<int>(std::floor(v.x() / v.z() / cell)),
                   static_cast<int>(std::floor(v.y() / v.z() / cell))});
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, 2e-5);
  const int n = static_cast<int>(2 * half / step);
  std::vector<std::int64_t> index(static_cast<std::size_t>(n * n), -1);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      const double x = step * (c - n / 2), y = step * (r - n / 2), z = z_at(x, y) + noise(rng);
      const int gx = static_cast<int>(std::floor(x / z / cell)),
                gy = static_cast<int>(std::floor(y / z / cell));
      bool hidden = false;
      for (int a = -1; a <= 1; ++a)
        for (int b = -1; b <= 1; ++b) hidden = hidden || shadow.count({gx + a, gy + b}) > 0;
      if (hidden) continue;
      index[static_cast<std::size_t>(r * n + c)] = static_cast<std::int64_t>(mesh.vertices.size());
      mesh.vertices.emplace_back(x, y, z);
    }
  return add_seen_grid_triangles(mesh, index, n, step);
}

TEST(Detect, APanelBeforeAWallThatFillsTheViewIsThePanel) {
  // A 0.5 x 0.4 m panel 5 cm before a wall 1.35 m square (upright and sloping), seen
  // round it up to its silhouette: the sensor sees the wall over five times as large as
  // the panel, and took the wall for the panel and left the panel out (0 of 5 found).
  const sim::scan::SynthScan door = sim::scan::synthesize_scan(small_door(3));
  for (const double slope : {0.0, 0.4}) {
    double behind = -1.0;  // the wall's plane through the panel's farthest point
    for (const Eigen::Vector3f& v : door.vertices) behind = std::max(behind, v.z() - slope * v.y());
    double wall_area = 0.0;
    const ScanRun r = run(small_door(3), [&](ingest::Mesh& mesh) {
      wall_area = add_wall_to_the_silhouette(
          mesh, [&](double, double y) { return behind + 0.05 + slope * y; }, 0.001, 0.675);
    });
    EXPECT_EQ(r.eval.matched, 5) << "slope " << slope;
    EXPECT_EQ(r.eval.false_alarms, 0) << "slope " << slope;
    EXPECT_GT(r.det.stats.background_area, 0.9 * wall_area) << "slope " << slope;
    EXPECT_LT(r.det.stats.background_area, 1.2 * wall_area) << "slope " << slope;
  }
}

TEST(Detect, TheSpacingIsThePanelsNotTheWallsBehindIt) {
  // A wall 1.1 m behind the panel with more samples than the panel, 2.5 times as far
  // apart (as a camera sees it): the scan's median spacing was the wall's, the finest
  // node 3 mm, and a map of 3 mm pixels lost the 5 mm defects. Without noise the outliers'
  // spikes also read as bumps 5 mm across there (the other generator's SW25: 8 false
  // alarms). The spacing is measured again on the panel, and the octree built at that.
  sim::scan::ScanOptions o;
  o.seed = 5;
  o.shape.width = 0.3;
  o.shape.height = 0.25;
  o.spacing = 0.0006;
  o.defects = 0;
  o.shape.window = false;
  o.shape.crease = false;
  o.shape.handle = false;
  o.noise = 0.0;
  o.outlier_fraction = 1e-3;
  o.planted = {{{0.07, 0.07}, 0.006, -1e-4}, {{0.20, 0.08}, 0.010, 5e-5}, {{0.13, 0.17}, 0.005, 1e-4}};
  const ScanRun r = run(o, [](ingest::Mesh& mesh) { add_wall_behind(mesh, false, 720, 2.0); });
  EXPECT_NEAR(r.det.stats.spacing, 0.0006, 0.0001);
  EXPECT_EQ(r.eval.matched, 3);
  EXPECT_EQ(r.eval.false_alarms, 0);
  EXPECT_LT(r.eval.max_position_error, 0.001);
}

TEST(Detect, NoisyScanReportsNothingOnTheStripBetweenWindowAndBorder) {
  SKIP_FULL_DOOR_UNDER_SANITIZER();
  // At 40 µm noise (twice the target scans') pieces of the narrow strip between the
  // window and the lower border, which no quadratic follows, once came out as dents of
  // 2-3 mm. Their surroundings are rough against the noise; a defect's are not.
  sim::scan::ScanOptions o;
  o.seed = 32;
  o.noise = 4e-5;
  o.defects = 12;
  const ScanRun r = run(o);
  EXPECT_EQ(r.eval.false_alarms, 0);
  EXPECT_GE(r.eval.matched, 11);
}

TEST(Detect, NoisyScanKeepsTheOctreesFeatureLeavesOutOfTheNoise) {
  // At 40 µm noise (twice the target scans') a 1 mm leaf's normal spread scatters about
  // its median by ~40 %. The eq. (3) threshold sqrt(floor² + feature_angle²) alone was
  // 1.8 times the floor and flagged 2 % of the leaves: 2 900 groups on this 0.2 m² panel,
  // each measured and reported as noise (17 k findings and seconds on a full door).
  sim::scan::ScanOptions o = small_door(51);
  o.noise = 4e-5;
  o.planted = {{{0.10, 0.08}, 0.012, -1.5e-4},
               {{0.22, 0.08}, 0.010, 1e-4},
               {{0.36, 0.10}, 0.006, -2e-4},
               {{0.20, 0.31}, 0.020, -3e-4}};
  const ScanRun r = run(o);
  const detect::DetectionStats& st = r.det.stats;
  EXPECT_EQ(r.eval.matched, 4);
  EXPECT_EQ(r.eval.false_alarms, 0);
  EXPECT_GE(st.leaf_sigma_threshold, st.noise_floor_sigma + 5.0 * st.noise_floor_spread);
  EXPECT_LT(st.feature_leaves, st.leaves / 1000);  // the handle's edges, not the noise
  EXPECT_LE(r.det.features.size(), 10u);
}

TEST(Detect, StrayPointsFarOffThePanelAreLeftOut) {
  // An outlier vertex tens or hundreds of metres off, meshed to the panel as a spike or
  // not used by any face. Once a spike 304 m off stretched the height map to 23 GB (and
  // tilted its plane: the spike's triangles outweighed the panel); a vertex 100 m off
  // made the octree too deep for 1 mm nodes and the scan was refused.
  sim::scan::ScanOptions o = small_door(61);
  const sim::scan::SynthScan scan = sim::scan::synthesize_scan(o);
  const report::TruthFile truth = report::truth_from_scan(scan);
  const auto detect_with = [&](const std::vector<Eigen::Vector3f>& extra, int spikes) {
    ingest::Mesh mesh;
    mesh.vertices = scan.vertices;
    mesh.triangles = scan.triangles;
    for (const auto& p : extra) {
      const auto k = static_cast<std::uint32_t>(mesh.vertices.size());
      mesh.vertices.push_back(p);
      for (int i = 0; i < spikes; ++i) {  // a spike: triangles from the stray vertex to the panel
        const auto& t = scan.triangles[static_cast<std::size_t>(1000 + 7919 * (k % 13) + i)];
        mesh.triangles.push_back({t[0], t[1], k});
      }
    }
    return detect::detect(mesh, detect::DetectConfig{});
  };
  const detect::Detection clean = detect_with({}, 0);
  const auto scored = [&](const detect::Detection& det) {
    report::DefectsFile found;
    for (const auto& f : det.defects)
      found.defects.push_back({report::class_name(f.defect.defect_class), f.defect});
    return report::evaluate(truth, found);
  };
  ASSERT_EQ(scored(clean).matched, 5);
  struct Case {
    const char* what;
    std::vector<Eigen::Vector3f> extra;
    int spikes;
    std::size_t stray;
  };
  for (const Case& c : {Case{"spikes 30 m off (kept in the octree, off the map)",
                             {{0.1f, 30.0f, 0.9f}, {30.0f, 0.1f, 9.0f}},
                             3,
                             0},
                        Case{"spikes 304 m off", {{0.08f, 304.0f, 0.9f}, {0.04f, 0.04f, 264.0f}}, 3, 6},
                        Case{"an unused vertex 100 m off", {{100.0f, 0.0f, 0.0f}}, 0, 0}}) {
    SCOPED_TRACE(c.what);
    const detect::Detection det = detect_with(c.extra, c.spikes);
    const report::Evaluation e = scored(det);
    EXPECT_EQ(e.matched, 5);
    EXPECT_EQ(e.false_alarms, 0);
    EXPECT_EQ(det.stats.stray_triangles, c.stray);
    EXPECT_LE(det.map.size(), clean.map.size() + clean.map.size() / 10);
    EXPECT_GT(std::abs(det.map.axes.row(2).dot(clean.map.axes.row(2))), 0.9999);  // the panel's plane
  }
}

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
      on_design += label <= -2 && r.det.features[static_cast<std::size_t>(-2 - label)].defect.defect_class ==
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

// A cylinder of radius R wrapped over `arc` metres round a vertical axis (the apex at
// z = 0), turned `tilt` rad about that axis and seen from the origin along +z, 0.9 m off,
// with 20 um of noise and cos² dents and bumps planted along the surface normal.
struct Planted {
  double s, t, diameter, height;  // s along the arc, t along the axis (m)
};
struct WrappedScan {
  double R, arc, tilt;
  std::vector<Planted> planted;

  Eigen::Vector3d point(double s, double t, double offset) const {
    const double a = s / R;  // round the axis
    // outwards from the axis R behind the apex, which is at z = 0
    const Eigen::Vector3d p((R + offset) * std::sin(a), t, (R + offset) * std::cos(a) - R);
    const Eigen::Vector3d q(std::cos(tilt) * p.x() + std::sin(tilt) * p.z(), p.y(),
                            -std::sin(tilt) * p.x() + std::cos(tilt) * p.z());
    return Eigen::Vector3d(q.x(), q.y(), 0.9 - q.z());  // the sensor at the origin, looking along +z
  }
  ingest::Mesh mesh(double step) const {
    ingest::Mesh m;
    std::mt19937_64 rng(5);
    std::normal_distribution<double> noise(0.0, 2e-5);
    const int ns = static_cast<int>(arc / step), nt = static_cast<int>(0.3 / step);
    for (int j = 0; j < nt; ++j)
      for (int i = 0; i < ns; ++i) {
        const double s = -0.5 * arc + i * step, t = -0.15 + j * step;
        double offset = noise(rng);  // outwards: towards the sensor
        for (const Planted& d : planted) {
          const double r = std::hypot(s - d.s, t - d.t);
          if (r < 0.5 * d.diameter)
            offset += d.height * std::pow(std::cos(std::numbers::pi * r / d.diameter), 2);
        }
        m.vertices.push_back(point(s, t, offset).cast<float>());
      }
    add_grid_triangles(m, nt, ns);
    return m;
  }
  // Every planted defect found once, in place and to 15 % in height; nothing else.
  void expect_found(const detect::Detection& det) const {
    std::vector<bool> found(planted.size(), false);
    for (const auto& f : det.defects) {
      bool matched = false;
      for (std::size_t i = 0; i < planted.size(); ++i) {
        const Planted& d = planted[i];
        if ((f.defect.position - point(d.s, d.t, 0.0)).norm() > 0.003) continue;
        EXPECT_FALSE(found[i]) << "found twice at s = " << d.s;
        matched = found[i] = true;
        EXPECT_NEAR(f.defect.height, d.height, std::max(1e-5, 0.15 * std::abs(d.height))) << "at s = " << d.s;
      }
      EXPECT_TRUE(matched) << "false alarm at " << f.defect.position.transpose() << " h " << f.defect.height
                           << " d " << f.defect.diameter;
    }
    for (std::size_t i = 0; i < planted.size(); ++i)
      EXPECT_TRUE(found[i]) << "missed at s = " << planted[i].s;
  }
};

TEST(Detect, DefectsOnAFendersSteepSidesAreFound) {
  // A fender wrapped +-64 degrees (0.74 m of arc at 0.33 m radius), seen 18 degrees off
  // its middle: one side is 82 degrees off the mean normal, the other 46. Dents and bumps
  // of 16-24 mm sit near the sides. On one map, even half the 64 mm window's quadratic
  // left tens of um of residual there, which made design features of the defects (the
  // other generator's SW43: 8 of 11 found).
  const WrappedScan scan{0.33,
                         0.74,
                         0.31,
                         {{-0.30, 0.04, 0.016, 2e-4},
                          {-0.29, -0.07, 0.024, -1.5e-4},
                          {0.30, 0.05, 0.020, -3e-4},
                          {0.29, -0.06, 0.018, 2e-4},
                          {0.00, 0.00, 0.020, -1e-4}}};
  scan.expect_found(detect::detect(scan.mesh(0.0006), detect::DetectConfig{}));
}

TEST(Detect, ATightFendersSidesAtFiftyFiveDegreesHoldNoPhantomDefects) {
  // 0.2 m radius wrapped +-56 degrees and seen 29 degrees off its middle (the other
  // generator's FW4 and FW16): on one map the quadratic reference left 30-140 um dents
  // and bumps on the sides that were not there (FW4: 3 false alarms), and here the
  // middle dent was lost. Such a panel is inspected in charts from 45 degrees on.
  const WrappedScan scan{0.2,
                         0.39,
                         0.5,
                         {{-0.15, 0.05, 0.012, -1.3e-4},
                          {-0.10, -0.08, 0.018, 1.5e-4},
                          {0.02, 0.02, 0.015, -1e-4},
                          {0.12, -0.05, 0.016, -2e-4},
                          {0.15, 0.09, 0.011, 1.2e-4}}};
  const detect::Detection det = detect::detect(scan.mesh(0.0005), detect::DetectConfig{});
  EXPECT_GE(det.stats.charts, 2u);
  scan.expect_found(det);
}

TEST(Detect, APanelWrappedRoundIsInspectedInCharts) {
  // A half cylinder (+-86 degrees at 0.25 m radius), as a scan merged from several views
  // gives it: its sides are edge-on to any one plane. Defects up to 76 degrees round,
  // 30 mm from the edges. On one map the sides were strips a few pixels wide, read as
  // long border features, and 6 of the 9 defects were lost. In charts no surface is more
  // than 30 degrees off its chart's axis.
  const double R = 0.25;
  std::vector<Planted> planted;
  for (const double degrees : {-76.0, -62.0, -35.0, 0.0, 33.0, 60.0, 76.5})
    planted.push_back({R * degrees * std::numbers::pi / 180.0, degrees > 0 ? 0.05 : -0.04,
                       std::abs(degrees) > 50 ? 0.014 : 0.022, degrees > 0 ? -1.2e-4 : 1.5e-4});
  planted.push_back({R * -1.33, 0.09, 0.018, -2e-4});  // 76 degrees
  planted.push_back({R * 1.33, -0.08, 0.016, 2.5e-4});
  // Seen square on, and turned 0.6 rad (34 degrees): then one side faces away from the
  // origin (120 degrees off the view), and its chart must still see dents as dents.
  for (const double tilt : {0.0, 0.6}) {
    SCOPED_TRACE(tilt);
    const WrappedScan scan{R, R * 3.0, tilt, planted};
    const detect::Detection det = detect::detect(scan.mesh(0.0006), detect::DetectConfig{});
    EXPECT_GE(det.stats.charts, 2u);
    scan.expect_found(det);
    for (const auto& f : det.features)  // the sides are no border features
      EXPECT_LT(f.defect.diameter, 0.1) << f.reason << " at " << f.defect.position.transpose();
  }
}

// The mesh as `views` pieces of consecutive triangles on vertices of their own, as views
// merged without fusing give it; the middle one wound the other way if `rewind_middle`.
ingest::Mesh as_views(const ingest::Mesh& mesh, int views, bool rewind_middle) {
  ingest::Mesh out;
  out.triangles = mesh.triangles;
  const std::size_t n = mesh.triangles.size();
  for (int k = 0; k < views; ++k) {
    std::vector<std::uint32_t> renumber(mesh.vertices.size(), std::numeric_limits<std::uint32_t>::max());
    for (std::size_t i = n * k / views; i < n * (k + 1) / views; ++i) {
      auto& t = out.triangles[i];
      for (auto& v : t) {
        if (renumber[v] == std::numeric_limits<std::uint32_t>::max()) {
          renumber[v] = static_cast<std::uint32_t>(out.vertices.size());
          out.vertices.push_back(mesh.vertices[v]);
        }
        v = renumber[v];
      }
      if (rewind_middle && k == views / 2) std::swap(t[1], t[2]);
    }
  }
  return out;
}

TEST(Detect, AWrappedPanelMergedFromViewsWoundEitherWayIsInspectedAsOne) {
  // The half cylinder below as three views that share no vertex: wound alike, the
  // winding check finds nothing to do (and the scan is inspected as it was); with the
  // middle view wound the other way, that view is rewound to agree with the others.
  const double R = 0.25;
  std::vector<Planted> planted;
  for (const double degrees : {-62.0, -35.0, 0.0, 33.0, 60.0})
    planted.push_back({R * degrees * std::numbers::pi / 180.0, degrees > 0 ? 0.05 : -0.04, 0.02,
                       degrees > 0 ? -1.2e-4 : 1.5e-4});
  const WrappedScan scan{R, R * 3.0, 0.0, planted};
  const ingest::Mesh whole = scan.mesh(0.0006);
  for (const bool rewind_middle : {false, true}) {
    SCOPED_TRACE(rewind_middle);
    const ingest::Mesh views = as_views(whole, 3, rewind_middle);
    const detect::Detection det = detect::detect(views, detect::DetectConfig{});
    EXPECT_GE(det.stats.charts, 2u);
    const std::size_t n = whole.triangles.size();
    EXPECT_EQ(det.stats.rewound_triangles, rewind_middle ? n * 2 / 3 - n / 3 : 0u);
    scan.expect_found(det);
  }
}

TEST(Detect, AWrappedPanelsSpacingIsItsOwnWithAWallBehind) {
  // As TheSpacingIsThePanelsNotTheWallsBehindIt, on a panel inspected in charts: each
  // chart's map sees only part of the wall, so the whole scan's background is looked for
  // before the charts (the other generator's SW49: 37 false alarms on a coarse map).
  const WrappedScan scan{0.25,
                         0.61,
                         0.2,
                         {{-0.22, 0.05, 0.012, -1.3e-4},
                          {-0.05, -0.06, 0.008, 1.5e-4},
                          {0.10, 0.02, 0.015, -1e-4},
                          {0.24, -0.05, 0.016, 1.2e-4}}};
  ingest::Mesh mesh = scan.mesh(0.0006);
  add_wall_behind(mesh, false, 1000, 2.0);
  const detect::Detection det = detect::detect(mesh, detect::DetectConfig{});
  EXPECT_GE(det.stats.charts, 2u);
  EXPECT_NEAR(det.stats.spacing, 0.0006, 0.0001);
  scan.expect_found(det);
}

TEST(Detect, ASideTurnedAwayFromTheSensorKeepsDentsAsDents) {
  // 260 degrees of a 0.15 m radius tube, as merged views give it: the charts past 90
  // degrees face away from the frame origin. Their maps look the way the whole scan's
  // would, along or against the normals (detector.cpp), or their dents would read as
  // bumps.
  const double R = 0.15;
  std::vector<Planted> planted;
  for (const auto& [degrees, t] : std::vector<std::pair<double, double>>{
           {-110.0, 0.0}, {-60.0, 0.03}, {0.0, -0.02}, {55.0, 0.0}, {112.0, 0.04}})
    planted.push_back({R * degrees * std::numbers::pi / 180.0, t, 0.018, -1.5e-4});
  planted.push_back({R * -1.6, -0.07, 0.016, 2e-4});  // 92 degrees
  planted.push_back({R * 1.65, 0.08, 0.016, 2e-4});   // 95 degrees
  const WrappedScan scan{R, R * 4.54, 0.0, planted};
  // Its triangles wound either way: normals outwards, or inwards (away from the sensor).
  for (const bool inwards : {false, true}) {
    SCOPED_TRACE(inwards);
    ingest::Mesh mesh = scan.mesh(0.0006);
    if (inwards)
      for (auto& t : mesh.triangles) std::swap(t[1], t[2]);
    const detect::Detection det = detect::detect(mesh, detect::DetectConfig{});
    EXPECT_GE(det.stats.charts, 3u);
    scan.expect_found(det);
    // The pictures: every chart's map, each defect labelled on the one chart that owns it.
    ASSERT_EQ(det.more_charts.size() + 1, det.stats.charts);
    std::vector<int> charts_labelling(det.defects.size(), 0);
    const auto count = [&](const std::vector<std::int32_t>& labels) {
      std::vector<bool> seen(det.defects.size(), false);
      for (const std::int32_t l : labels)
        if (l >= 0) seen[static_cast<std::size_t>(l)] = true;
      for (std::size_t k = 0; k < seen.size(); ++k) charts_labelling[k] += seen[k];
    };
    count(det.labels);
    for (const auto& chart : det.more_charts) count(chart.labels);
    for (std::size_t k = 0; k < det.defects.size(); ++k) EXPECT_EQ(charts_labelling[k], 1) << "defect " << k;
    // The report: a panel per chart, each defect ringed and numbered on its own chart.
    const report::ReportLayout layout = report::layout_report(det, {"wrapped.ply", ""});
    ASSERT_EQ(layout.panels.size(), det.stats.charts);
    ASSERT_GE(layout.marks.size(), det.defects.size());
    for (std::size_t i = 0; i < layout.marks.size(); ++i) {
      const auto& m = layout.marks[i];
      const report::Box& map = layout.panels[m.panel].map;
      EXPECT_TRUE(m.label.box.inside(map)) << m.label.text;
      EXPECT_TRUE(m.cx >= map.x && m.cx < map.right() && m.cy >= map.y && m.cy < map.bottom())
          << m.label.text;
      // First each defect on the chart that owns it, then echoes on the others.
      EXPECT_EQ(m.echo, i >= det.defects.size());
      EXPECT_EQ(m.panel == report::defect_panels(det)[m.defect], !m.echo) << m.label.text;
    }
    EXPECT_GE(layout.colour_bar.x,
              layout.panels[0].title_text.box.right());  // titles clear of the side column
    for (std::size_t p = 1; p < layout.panels.size(); ++p)
      EXPECT_GE(layout.panels[p].map.y, layout.panels[p - 1].map.bottom());  // stacked, apart
    EXPECT_LE(layout.panels.back().map.bottom(), layout.height);
    // The marked PLY: each planted defect's centre coloured as its class, wherever it lies.
    const auto colours = report::marked_vertex_colours(mesh, det);
    for (const Planted& d : planted) {
      const Eigen::Vector3f centre = scan.point(d.s, d.t, d.height).cast<float>();
      std::size_t nearest = 0;
      for (std::size_t v = 0; v < mesh.vertices.size(); ++v)
        if ((mesh.vertices[v] - centre).squaredNorm() < (mesh.vertices[nearest] - centre).squaredNorm())
          nearest = v;
      const std::array<std::uint8_t, 3> expected =
          d.height < 0 ? std::array<std::uint8_t, 3>{220, 30, 30} : std::array<std::uint8_t, 3>{30, 60, 230};
      EXPECT_EQ(colours[nearest], expected) << "defect at s = " << d.s;
    }
  }
}

// Defects 'diameter' across at (degrees round the axis, t along it): dents on the
// negative side, bumps on the positive.
std::vector<Planted> round_the_axis(double R, const std::vector<std::pair<double, double>>& at,
                                    double diameter, double depth) {
  std::vector<Planted> planted;
  for (const auto& [degrees, t] : at)
    planted.push_back({R * degrees * std::numbers::pi / 180.0, t, diameter, degrees < 0 ? -depth : depth});
  return planted;
}

// The scan's points alone, shuffled (an unorganised cloud), meshed as dentmark meshes one.
ingest::Mesh as_cloud(const WrappedScan& scan, double step) {
  ingest::Mesh cloud;
  cloud.vertices = scan.mesh(step).vertices;
  std::shuffle(cloud.vertices.begin(), cloud.vertices.end(), std::mt19937(8));
  ingest::mesh_point_cloud(cloud);
  return cloud;
}

TEST(Detect, AWrappedCloudsSidesAreMeshedAndInspected) {
  // The 260-degree tube as an unorganised cloud (merged views, points shuffled): meshed
  // in charts (ingest's fold_mesher), its defects past 90 degrees from the sensor are
  // found as on the mesh (the other generator's SW86 and SW91 lost those on the sides
  // their sensor-view triangulation could not mesh).
  const double R = 0.15;
  const WrappedScan scan{R, R * 4.54, 0.0,
                         round_the_axis(R,
                                        {{-110.0, 0.0},
                                         {-95.0, -0.05},
                                         {-60.0, 0.03},
                                         {0.0, -0.02},
                                         {70.0, 0.0},
                                         {100.0, 0.06},
                                         {112.0, -0.04}},
                                        0.018, 1.5e-4)};
  const detect::Detection det = detect::detect(as_cloud(scan, 0.0006), detect::DetectConfig{});
  EXPECT_GE(det.stats.charts, 3u);
  scan.expect_found(det);
}

TEST(Detect, ASteepFendersCloudFromOneViewIsMeshedInCharts) {
  // One view of a 0.2 m fender to +-86 degrees, as an unorganised cloud: its sides are
  // seen nearly edge-on, where the sensor-view triangulation lost the defects at 70
  // degrees (5 of 7 found); meshed in charts, all are.
  const double R = 0.2;
  const WrappedScan scan{R, R * 2 * 86.0 * std::numbers::pi / 180.0, 0.0,
                         round_the_axis(R,
                                        {{-70.0, 0.0},
                                         {-55.0, -0.05},
                                         {-30.0, 0.03},
                                         {0.0, -0.02},
                                         {40.0, 0.0},
                                         {62.0, 0.06},
                                         {72.0, -0.04}},
                                        0.016, 1.2e-4)};
  const ingest::Mesh cloud = as_cloud(scan, 0.0005);
  EXPECT_GE(cloud.cloud_charts, 2u);
  scan.expect_found(detect::detect(cloud, detect::DetectConfig{}));
}

TEST(Detect, DefectsNearAWrappedPanelsOwnEdgeAreFound) {
  // The 260-degree tube's own edges lie 30-45 degrees off their charts' axes. The first
  // fit leaves ~20 um there; the robust refits left the candidates along the edge out,
  // and with nothing beyond a border to interpolate from, the next fit extrapolated into
  // them: -0.6 mm at the edge, and one 0.34 m long border feature swallowed the dent 15
  // degrees (39 mm) from it. Pieces touching a chart's border now stay in the refits.
  // (Closer still, 8 degrees off, a defect's candidate still joins the edge's faint band.)
  const double R = 0.15;
  std::vector<Planted> planted;
  for (const auto& [degrees, t, height] : std::vector<std::tuple<double, double, double>>{
           {-115.0, 0.0, -1.5e-4}, {-95.0, -0.05, -1.5e-4}, {112.0, 0.05, 1.5e-4}, {118.0, -0.04, 1.5e-4}})
    planted.push_back({R * degrees * std::numbers::pi / 180.0, t, 0.018, height});
  const WrappedScan scan{R, R * 4.54, 0.0, planted};
  const detect::Detection det = detect::detect(scan.mesh(0.0006), detect::DetectConfig{});
  scan.expect_found(det);
}

TEST(Detect, PapersCaseFindsTheTallBumpNotTheHandle) {
  // §V: ~32 000 points of a door, a bump 9 mm wide and 11 mm high, the handle.
  sim::scan::ScanOptions o;
  o.spacing = 0.0045;
  o.noise = 1e-4;
  o.defects = 0;
  o.planted = {{{0.30, 0.22}, 0.009, 0.011}};
  const ScanRun r = run(o);
  EXPECT_EQ(r.eval.matched, 1);
  EXPECT_EQ(r.eval.false_alarms, 0);
  EXPECT_LE(r.eval.max_position_error, 0.005);
  ASSERT_EQ(r.det.defects.size(), 1u);
  EXPECT_EQ(r.det.defects[0].defect.defect_class, protocol::DefectClass::kBump);
}

}  // namespace
}  // namespace dentmark
