// End to end on synthetic doors with ground truth: dents and bumps found where they
// are, with their depth; design features never reported.
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
#include "detect_scans.h"

namespace dentmark {
namespace {

using namespace detect_test;

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

TEST(Detect, PapersCaseFindsTheTallBumpNotTheHandle) {
  // §V: ~32 000 points of a door, a bump 9 mm wide and 11 mm high, the handle.
  sim::scan::ScanOptions o;
  o.spacing = 0.0045;
  o.noise = 1e-4;
  o.defects = 0;
  o.planted = {{{0.30, 0.22}, 0.009, 0.011}};
  const ScanRun r = run(o);
  expect_only_the_papers_bump(r);
}

}  // namespace
}  // namespace dentmark
