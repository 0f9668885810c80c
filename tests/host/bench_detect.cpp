// Speed and quality of detection on synthetic door scans.
//   BM_Detect/<shuffled>:  detection alone on a ~9 M-triangle, 0.39 mm door scan
//                           (items/s = triangles/s), triangles in sensor or random order.
//   BM_ReadDetectWrite:     binary PLY read + detection + JSON write, the whole job.
//   BM_BoxMean/<k>:         the deviation's windowed mean on a door-sized map (1300 x 1000
//                           pixels, k x k windows; items/s = pixels/s).
//   BM_ReferenceFit:        the reference surface on a door-sized map with a character line
//                           (1200 x 950 pixels of 1 mm): a fit, then a refit without a
//                           dozen defects, as detection does (items/s = pixels fitted/s).
//   BM_QualityOverSeeds:    recall / false alarms / errors over many seeds (counters).
//   BM_WindingCheck:        the winding check a wrapped scan pays (opposed neighbours and
//                           parts), on the ~9 M-triangle door (items/s = triangles/s).
//   BM_Rewind:              rewinding that door after half its triangles were rewound at
//                           random (orient_consistently; items/s = triangles/s).
#include <benchmark/benchmark.h>

#include <filesystem>
#include <memory>
#include <opencv2/core.hpp>
#include <random>

#include "../../host/detect/box_mean.h"
#include "dentmark/common/huge_pages.h"
#include "dentmark/common/ingest/mesh_writer.h"
#include "dentmark/host/detect/detector.h"
#include "dentmark/host/detect/linear_octree.h"
#include "dentmark/host/detect/reference_surface.h"
#include "dentmark/host/ingest/orient_triangles.h"
#include "dentmark/host/ingest/read_mesh.h"
#include "dentmark/host/report/defects_json.h"
#include "dentmark/host/report/evaluate.h"
#include "dentmark/host/report/scan_truth.h"
#include "dentmark/sim/scan/sls_scan.h"

namespace {

using namespace dentmark;

// As the 'dentmark' command does: freed memory stays in the heap for the next stage (and
// here the next iteration), so the figures are the algorithm's, not the VM's page faults.
const bool heap_kept = [] {
  prepare_heap_for_big_jobs();  // as the command does
  return true;
}();

sim::scan::ScanOptions big_door(bool shuffled) {
  sim::scan::ScanOptions o;
  o.seed = 99;
  o.shape.width = 1.2;
  o.shape.height = 0.95;
  o.spacing = 0.00039;  // ~9 M triangles
  o.defects = 12;
  o.outlier_fraction = 1e-5;
  o.shuffle = shuffled;
  return o;
}

const ingest::Mesh& big_mesh(bool shuffled) {
  static std::unique_ptr<ingest::Mesh> cache[2];
  auto& m = cache[shuffled ? 1 : 0];
  if (!m) {
    auto scan = sim::scan::synthesize_scan(big_door(shuffled));
    m = std::make_unique<ingest::Mesh>();
    m->vertices = std::move(scan.vertices);
    m->triangles = std::move(scan.triangles);
  }
  return *m;
}

void BM_Detect(benchmark::State& state) {
  const ingest::Mesh& mesh = big_mesh(state.range(0) != 0);
  std::size_t found = 0, bytes = 0;
  for (auto _ : state) {
    auto det = detect::detect(mesh, detect::DetectConfig{});
    found = det.defects.size();
    bytes = det.stats.working_bytes;
    benchmark::DoNotOptimize(det);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * mesh.triangles.size()));
  state.counters["triangles"] = static_cast<double>(mesh.triangles.size());
  state.counters["defects"] = static_cast<double>(found);
  state.counters["bytes_per_triangle"] =
      static_cast<double>(bytes) / static_cast<double>(mesh.triangles.size());
}
BENCHMARK(BM_Detect)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

// The octree's leaf sums alone (eq. 1-2 for every occupied finest node), 1 mm nodes.
void BM_OctreeBuild(benchmark::State& state) {
  const ingest::Mesh& mesh = big_mesh(state.range(0) != 0);
  std::size_t leaves = 0;
  for (auto _ : state) {
    const auto tree = detect::LinearOctree::build(mesh, 0.001);
    leaves = tree.leaves().size();
    benchmark::DoNotOptimize(tree);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * mesh.triangles.size()));
  state.counters["leaves"] = static_cast<double>(leaves);
}
BENCHMARK(BM_OctreeBuild)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

void BM_WindingCheck(benchmark::State& state) {
  const ingest::Mesh& mesh = big_mesh(false);
  bool opposed = true;
  std::size_t parts = 0;
  for (auto _ : state) {
    opposed = ingest::has_opposed_neighbours(mesh);
    parts = ingest::large_parts(mesh, mesh.triangles.size() / 100);
  }
  if (opposed || parts != 1) state.SkipWithError("the door should be one consistent part");
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * mesh.triangles.size()));
}
BENCHMARK(BM_WindingCheck)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

void BM_Rewind(benchmark::State& state) {
  static const ingest::Mesh rewound = [] {
    ingest::Mesh m = big_mesh(false);
    std::mt19937 rng(3);
    for (auto& t : m.triangles)
      if (rng() & 1) std::swap(t[1], t[2]);
    return m;
  }();
  std::size_t flipped = 0;
  for (auto _ : state) {
    const auto oriented = ingest::orient_consistently(rewound);
    flipped = oriented ? oriented->flipped : 0;
    benchmark::DoNotOptimize(oriented);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * rewound.triangles.size()));
  state.counters["rewound"] = static_cast<double>(flipped);
}
BENCHMARK(BM_Rewind)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

void BM_ReadDetectWrite(benchmark::State& state) {
  const std::string dir = std::filesystem::temp_directory_path().string();
  const std::string ply = dir + "/dentmark_bench_door.ply", json = dir + "/dentmark_bench_door.json";
  ingest::write_ply(ply, big_mesh(true));
  for (auto _ : state) {
    const ingest::Scan scan = ingest::open_scan(ply);
    const auto det = detect::detect(scan.mesh, detect::DetectConfig{});
    report::write_text_file(
        json, report::defects_to_json(det, {ply, scan.input_points, scan.mesh.triangle_count()}).dump(1));
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * big_mesh(true).triangles.size()));
  std::filesystem::remove(ply);
  std::filesystem::remove(json);
}
void BM_BoxMean(benchmark::State& state) {
  const int k = static_cast<int>(state.range(0));
  cv::Mat values(1000, 1300, CV_32F), weights(values.size(), CV_32F), out;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int r = 0; r < values.rows; ++r)
    for (int c = 0; c < values.cols; ++c) {
      const float w = u(rng) < 0.05f ? 0.0f : u(rng);  // a few pixels unseen
      weights.at<float>(r, c) = w, values.at<float>(r, c) = w * 1e-5f * (u(rng) - 0.5f);
    }
  for (auto _ : state) {
    detect::box_mean(values, weights, k, 0.3f * static_cast<float>(k * k), out);
    benchmark::DoNotOptimize(out.data);
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(values.total()));
}
BENCHMARK(BM_BoxMean)->Arg(3)->Arg(7)->Arg(15)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ReferenceFit(benchmark::State& state) {
  // A gently curved panel with a 0.1 rad fold rounded at 2 mm, at 20 degrees across the
  // map, and 20 um of noise.
  detect::HeightMap map;
  map.pixel = 0.001, map.cols = 1200, map.rows = 950;
  map.u0 = -0.6, map.v0 = -0.475;
  const std::size_t n = map.size();
  map.weight.assign(n, 1.0f), map.cos_tilt.assign(n, 1.0f);
  map.u.resize(n), map.v.resize(n), map.w.resize(n);
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 20e-6);
  for (int r = 0; r < map.rows; ++r)
    for (int c = 0; c < map.cols; ++c) {
      const std::size_t k = static_cast<std::size_t>(r) * map.cols + c;
      const double u = map.u0 + (c + 0.5) * map.pixel, v = map.v0 + (r + 0.5) * map.pixel;
      const double t = -0.342 * u + 0.940 * (v - 0.1);
      map.u[k] = static_cast<float>(u), map.v[k] = static_cast<float>(v);
      map.w[k] = static_cast<float>(0.3 * u * u + 0.2 * v * v + 0.05 * std::sqrt(t * t + 4e-6) + noise(rng));
    }
  // A dozen 20 mm defects' pixels, left out of the refit.
  std::vector<float> without = map.weight;
  for (int d = 0; d < 12; ++d) {
    const int r0 = 60 + 70 * d, c0 = 80 + 90 * d;
    for (int r = r0; r < r0 + 20; ++r)
      for (int c = c0; c < c0 + 20; ++c) without[static_cast<std::size_t>(r) * map.cols + c] = 0.0f;
  }
  for (auto _ : state) {
    detect::ReferenceSurface surface(map, 0.064);
    benchmark::DoNotOptimize(surface.fit(map.weight).data());
    benchmark::DoNotOptimize(surface.fit(without).data());
  }
  state.SetItemsProcessed(state.iterations() * 2 * static_cast<std::int64_t>(n));
}
BENCHMARK(BM_ReferenceFit)->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK(BM_ReadDetectWrite)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

void BM_QualityOverSeeds(benchmark::State& state) {
  report::Evaluation total;
  for (auto _ : state) {
    total = {};
    for (int seed = 1; seed <= state.range(0); ++seed) {
      sim::scan::ScanOptions o;
      o.seed = static_cast<std::uint64_t>(1000 + seed);
      o.defects = 12;
      o.min_diameter = 0.005;
      o.min_depth = 5e-5;
      o.outlier_fraction = seed % 2 ? 0.0 : 1e-4;
      o.dropouts = seed % 3;
      o.holes = state.range(1) ? seed % 3 : 0;
      o.shuffle = seed % 2 == 0;
      auto scan = sim::scan::synthesize_scan(o);
      ingest::Mesh mesh;
      mesh.vertices = std::move(scan.vertices);
      mesh.triangles = std::move(scan.triangles);
      const auto det = detect::detect(mesh, detect::DetectConfig{});
      const report::TruthFile truth = report::truth_from_scan(scan);
      report::DefectsFile found;
      for (const auto& f : det.defects)
        found.defects.push_back({report::class_name(f.defect.defect_class), f.defect});
      total.add(report::evaluate(truth, found));
    }
  }
  state.counters["recall"] = total.recall();
  state.counters["precision"] = total.precision();
  state.counters["recall_10mm_50um"] = total.classes[0].recall();
  state.counters["recall_5mm_100um"] = total.classes[1].recall();
  state.counters["recall_holes"] = total.classes[2].recall();
  state.counters["holes"] = total.classes[2].total;
  state.counters["false_alarms_per_m2"] = total.false_alarms_per_m2();
  state.counters["on_features"] = total.on_features;
  state.counters["max_pos_err_mm"] = 1e3 * total.max_position_error;
  state.counters["mean_depth_err_um"] = 1e6 * total.mean_depth_error;
  state.counters["depth_ok_frac"] =
      total.depth_matched ? static_cast<double>(total.depth_within_tolerance) / total.depth_matched : 0;
  state.counters["truth"] = total.truth;
}
// Args: seeds, with holes (0/1: without holes the scans are those of earlier releases).
BENCHMARK(BM_QualityOverSeeds)->Args({20, 0})->Args({20, 1})->Iterations(1)->Unit(benchmark::kSecond);

}  // namespace
