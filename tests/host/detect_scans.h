#pragma once
// Shared by the end-to-end detection tests (test_detect*.cpp): a synthetic scan run
// through the detector and scored against its truth, the small door, and meshes of what
// a scanner sees beside the panel.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <random>
#include <vector>

#include "dentmark/host/detect/detector.h"
#include "dentmark/host/report/defects_json.h"
#include "dentmark/host/report/evaluate.h"
#include "dentmark/host/report/scan_truth.h"
#include "dentmark/sim/scan/sls_scan.h"

// Full 1.0 x 0.8 m doors take a few seconds here and many minutes in a Debug build under
// AddressSanitizer; the smaller scans of the other tests run the same code there.
#if defined(__SANITIZE_ADDRESS__)
#define SKIP_FULL_DOOR_UNDER_SANITIZER() GTEST_SKIP() << "full-door scan: run by the native preset"
constexpr bool kSanitized = true;  // (a small door takes ~2 minutes there)
#else
#define SKIP_FULL_DOOR_UNDER_SANITIZER() (void)0
constexpr bool kSanitized = false;
#endif

namespace dentmark::detect_test {

struct ScanRun {
  report::Evaluation eval;
  detect::Detection det;
};

// `more` adds to the scan what the scanner saw besides the panel.
inline ScanRun run(const sim::scan::ScanOptions& o, const std::function<void(ingest::Mesh&)>& more = {},
                   const detect::DetectConfig& cfg = {}) {
  sim::scan::SynthScan scan = sim::scan::synthesize_scan(o);
  ingest::Mesh mesh;
  mesh.vertices = scan.vertices;
  mesh.triangles = scan.triangles;
  if (more) more(mesh);
  ScanRun r;
  r.det = detect::detect(mesh, cfg);
  const report::TruthFile truth = report::truth_from_scan(scan);
  report::DefectsFile found;
  for (const auto& f : r.det.defects)
    found.defects.push_back({report::class_name(f.defect.defect_class), f.defect});
  r.eval = report::evaluate(truth, found);
  return r;
}

// A small door (0.5 x 0.4 m) at 0.5 mm / 20 µm with defects at the target limits.
// The paper's case (§V): its one bump, and nothing else, found as a bump within 5 mm.
inline void expect_only_the_papers_bump(const ScanRun& r) {
  EXPECT_EQ(r.eval.matched, 1);
  EXPECT_EQ(r.eval.false_alarms, 0);
  EXPECT_LE(r.eval.max_position_error, 0.005);
  ASSERT_EQ(r.det.defects.size(), 1u);
  EXPECT_EQ(r.det.defects[0].defect.defect_class, protocol::DefectClass::kBump);
}

inline sim::scan::ScanOptions small_door(std::uint64_t seed) {
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

// Two triangles per cell of a rows x cols grid of vertices stored row by row.
inline void add_grid_triangles(ingest::Mesh& mesh, int rows, int cols) {
  for (int r = 0; r + 1 < rows; ++r)
    for (int c = 0; c + 1 < cols; ++c) {
      const auto k = [&](int dr, int dc) { return static_cast<std::uint32_t>((r + dr) * cols + c + dc); };
      mesh.triangles.push_back({k(0, 0), k(1, 0), k(0, 1)});
      mesh.triangles.push_back({k(0, 1), k(1, 0), k(1, 1)});
    }
}

// Two triangles per cell of an n x n grid of samples `step` apart whose four corners were
// seen (index: the vertex of each grid point, -1 where unseen). Returns their area.
inline double add_seen_grid_triangles(ingest::Mesh& mesh, const std::vector<std::int64_t>& index, int n,
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
inline double add_wall_behind(ingest::Mesh& mesh, bool floor, int n, double z = 1.5) {
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

}  // namespace dentmark::detect_test
