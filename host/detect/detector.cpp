#include "dentmark/host/detect/detector.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "along_feature.h"
#include "background.h"
#include "border_zone.h"
#include "charts.h"
#include "coarse_defects.h"
#include "dentmark/common/nth_smallest.h"
#include "dentmark/host/detect/apex_fit.h"
#include "dentmark/host/detect/grouping.h"
#include "dentmark/host/detect/linear_octree.h"
#include "dentmark/host/detect/reference_surface.h"
#include "dentmark/host/ingest/orient_triangles.h"
#include "dentmark/host/ingest/units.h"
#include "design_rules.h"
#include "deviation.h"
#include "dilate.h"
#include "findings.h"
#include "holes.h"
#include "local_surface_fit.h"
#include "measure_candidate.h"
#include "patch_normal.h"
#include "stray_points.h"
#include "threads.h"

namespace dentmark::detect {
namespace {

using Clock = std::chrono::steady_clock;

// Robust standard deviations of the leaves' normal spread (eq. 3) above its median that
// a feature leaf must reach at least.
constexpr double kLeafNoiseTail = 6.0;
// Winding checks (winding_suspect): a median leaf spread this high is no noise (σ² = 1 -
// |mean normal|²: 0.5 is a mean normal of 0.87); a leaf whose mean normal is under half
// its area has normals over 120° apart in it; a consistent panel has next to none.
constexpr double kWindingNoiseFloor = 0.5;
constexpr double kOpposedLeafMeanNormal = 0.5;
constexpr double kOpposedLeafShare = 1e-4;
// ... and parts of at least this many triangles (or 1 % of them) may be views merged
// without sharing an edge, each wound its own way.
constexpr std::size_t kLargePart = 1000;
// Coarse scans: at this spacing or more a 9 mm defect spans under four samples and a map
// pixel of two spacings averages it away; defects are then found on the vertices
// (coarse_defects.h). The local surface is fitted over an annulus from kCoarseInner to
// kCoarseOuter spacings round each vertex (its first ring of neighbours left out); a
// vertex over kCoarseMember robust σ joins a neighbour's group (hysteresis under the
// detection threshold; a Gaussian sample passes it 1 time in 700).
constexpr double kCoarseSpacing = 0.0025;
constexpr double kCoarseInner = 1.6;
constexpr double kCoarseOuter = 6.0;
constexpr double kCoarseMember = 3.0;
// Vertices within this many edges of the mesh's boundary are no defect's (a rolled edge).
constexpr int kCoarseBorderRings = 2;

// A candidate: connected pixels over the deviation test or in an eq. (3)-(4) group.
struct Candidate {
  std::vector<std::int32_t> pixels;
  bool has_deviation = false;  // found by the deviation test, not only by eq. (3)
  CandidateShape shape;
};

// A design feature as reported: centred on its weighted mean point, its height the
// extreme deviation in it, its diameter its length.
Finding design_finding(const Candidate& comp, const HeightMap& map, const std::vector<float>& deviation,
                       const char* why) {
  Finding f;
  f.pixels = static_cast<int>(comp.pixels.size());
  f.reason = why;
  protocol::Defect& d = f.defect;
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  double ws = 0.0, extreme = 0.0;
  for (auto k : comp.pixels) {
    p += map.weight[k] * Eigen::Vector3d(map.u[k], map.v[k], map.w[k]);
    ws += map.weight[k];
    const float dv = deviation[static_cast<std::size_t>(k)];
    if (std::isfinite(dv) && std::abs(dv) > std::abs(extreme)) extreme = dv;
  }
  d.defect_class = protocol::DefectClass::kDesignFeature;
  d.position = map.to_scan(p.x() / ws, p.y() / ws, p.z() / ws);
  d.normal = map.axes.row(2).transpose();
  d.diameter = comp.shape.length;
  d.area = comp.shape.area;
  d.height = extreme;
  d.score = 1.0;
  return f;
}

Detection inspect(const ingest::MeshView& input, const ingest::MeshView& mesh,
                  std::unique_ptr<const LinearOctree> tree_ptr, const DetectConfig& cfg, Detection out,
                  bool remeasure, Clock::time_point start, Clock::time_point t0,
                  const Eigen::Vector3d& chart_w = Eigen::Vector3d::Zero());
Detection inspect_charts(const ingest::MeshView& input, const ingest::MeshView& mesh,
                         std::unique_ptr<const LinearOctree> tree_ptr, const Charts& charts, int facing,
                         const DetectConfig& cfg, Detection out);

// The map pixels of the octree's feature groups (eq. 3-4 candidates).
std::vector<long> pixels_of_groups(const LinearOctree& tree,
                                   const std::vector<std::vector<std::uint32_t>>& groups,
                                   const HeightMap& map) {
  std::vector<long> pixels;
  for (const auto& g : groups)
    for (auto l : g) {
      const Eigen::Vector3d q = map.to_map(tree.leaves()[l].centroid.cast<double>());
      if (const long k = map.pixel_of(q.x(), q.y()); k >= 0) pixels.push_back(k);
    }
  return pixels;
}

// The seen pixels off the border zone.
cv::Mat interior_of(const HeightMap& map, const cv::Mat& edge_zone) {
  cv::Mat interior(map.rows, map.cols, CV_8U);
#pragma omp parallel for schedule(static)
  for (std::int64_t k = 0; k < static_cast<std::int64_t>(map.size()); ++k)
    interior.data[k] = map.weight[static_cast<std::size_t>(k)] > 0.0f && !edge_zone.data[k] ? 255 : 0;
  return interior;
}

// Design features by shape (and the fold lines), and the pieces next to them; those that
// touch a border apart (design_rules.h: a rolled edge's band has no shoulders).
cv::Mat near_design_zone(const std::vector<Candidate>& comps, const cv::Mat& fold_px,
                         const cv::Mat& edge_zone, const HeightMap& map, const DetectConfig& cfg) {
  cv::Mat design(map.rows, map.cols, CV_8U, cv::Scalar(0)),
      border_design(map.rows, map.cols, CV_8U, cv::Scalar(0));
  for (const Candidate& comp : comps)
    if (!comp.pixels.empty() && design_reason(comp.shape, cfg))
      for (auto k : comp.pixels) (comp.shape.touches_edge ? border_design : design).data[k] = 255;
  design |= fold_px;  // a fold line is a design feature wherever it shows, even in pieces
  return design_surroundings(design, border_design, edge_zone, map.pixel);
}

// The holes' pixels and what was seen through them, widened by 2 mm: their rim is theirs,
// not a dent's.
cv::Mat hole_zone_of(const std::vector<HoleRegion>& holes, int rows, int cols, double h) {
  cv::Mat zone(rows, cols, CV_8U, cv::Scalar(0));
  for (const auto& hr : holes) {
    for (auto k : hr.pixels) zone.data[k] = 255;
    for (auto k : hr.seen_deep) zone.data[k] = 255;
  }
  const int rad = std::max(2, static_cast<int>(std::lround(0.002 / h)));
  dilate_in_strips(zone, zone, cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * rad + 1, 2 * rad + 1}));
  return zone;
}

// The 8-connected components of 'any' (labels: their numbers, 0 for none), each with its
// pixels, its shape, and whether the deviation test ('cand') flagged any of them; index
// 0 is the background.
std::vector<Candidate> candidate_components(const cv::Mat& any, const cv::Mat& cand, const HeightMap& map,
                                            const cv::Mat& edge_zone, cv::Mat& labels) {
  const int ncomp = cv::connectedComponents(any, labels, 8, CV_32S);
  std::vector<Candidate> comps(static_cast<std::size_t>(std::max(ncomp, 1)));
  const int* lab = labels.ptr<int>();
  for (std::int32_t k = 0; k < map.rows * map.cols; ++k)
    if (lab[k] > 0) {
      comps[static_cast<std::size_t>(lab[k])].pixels.push_back(k);
      if (cand.data[k]) comps[static_cast<std::size_t>(lab[k])].has_deviation = true;
    }
  for (auto& comp : comps)
    if (!comp.pixels.empty()) comp.shape = shape_of(comp.pixels, map, edge_zone);
  return comps;
}

// The scan's own samples under the candidates' bounding boxes (2 pixels wider), for
// their apex depth.
PixelSamples samples_around(const ingest::MeshView& mesh, const HeightMap& map,
                            const std::vector<const Candidate*>& candidates) {
  const int rows = map.rows, cols = map.cols;
  std::vector<std::uint8_t> select(map.size(), 0);
  for (const Candidate* comp : candidates) {
    int c0 = cols, c1 = 0, r0 = rows, r1 = 0;
    for (auto k : comp->pixels)
      c0 = std::min(c0, k % cols), c1 = std::max(c1, k % cols), r0 = std::min(r0, k / cols),
      r1 = std::max(r1, k / cols);
    for (int r = std::max(0, r0 - 2); r <= std::min(rows - 1, r1 + 2); ++r)
      std::fill_n(select.begin() + r * cols + std::max(0, c0 - 2),
                  std::min(cols - 1, c1 + 2) - std::max(0, c0 - 2) + 1, 1);
  }
  return PixelSamples(mesh, map, select);
}

// A measured candidate as a finding: where it is, its size and score, and its class with
// the reason (an outlier's spike, rough surroundings, under the noise-adapted threshold,
// or a dent or bump). 'sigma3': the deviation noise at the finest scale.
Finding classify_candidate(const Candidate& comp, const Measurement& m, const Eigen::Vector3d& normal,
                           const HeightMap& map, const DetectConfig& cfg, double sigma3, bool outlier) {
  Finding f;
  f.pixels = static_cast<int>(comp.pixels.size());
  protocol::Defect& d = f.defect;
  d.position = map.to_scan(m.position.x(), m.position.y(), m.position.z());
  d.normal = normal;
  d.height = m.height;
  d.diameter = std::max(map.pixel, 4.0 * m.half_radius);
  d.area = disc_area(d.diameter);
  const double snr = std::abs(m.peak_deviation) / sigma3;
  d.score = score_of(snr, cfg.detection_sigma);
  if (outlier || m.single_sample) {
    d.defect_class = protocol::DefectClass::kNoise;
    f.reason = "isolated spike (outlier)";
  } else if (m.rough_surroundings) {
    d.defect_class = protocol::DefectClass::kDesignFeature;
    f.reason = "surroundings not a smooth panel (between features)";
  } else if (std::abs(m.height) < cfg.min_height || snr < cfg.detection_sigma) {
    d.defect_class = protocol::DefectClass::kNoise;
    f.reason = "below the noise-adapted threshold";
  } else {
    d.defect_class = m.height < 0 ? protocol::DefectClass::kDent : protocol::DefectClass::kBump;
    f.reason = m.height < 0 ? "depression" : "protrusion";
  }
  return f;
}

// With a background found, the spacing was measured over it too, and the finest node
// follows the spacing: the panel's own spacing if its finest node differs by more than
// 10 % from h, else 0.
double panel_spacing_if_other(const ingest::MeshView& mesh, const LinearOctree& tree,
                              const std::vector<std::uint8_t>& background_leaf, const DetectConfig& cfg,
                              double h) {
  const double on_panel = panel_spacing(mesh, tree, background_leaf);
  return on_panel > 0.0 && std::abs(std::max(cfg.finest_node_size, 2.0 * on_panel) - h) > 0.1 * h ? on_panel
                                                                                                  : 0.0;
}

Detection detect_at_spacing(const ingest::MeshView& input, const DetectConfig& cfg, double spacing,
                            bool remeasure, bool check_winding = false);

// detect_at_spacing once more at the panel's spacing; the first try shows as "spacing".
Detection start_over(const ingest::MeshView& input, const DetectConfig& cfg, double spacing,
                     Clock::time_point start) {
  const auto first_try = Clock::now() - start;
  Detection again = detect_at_spacing(input, cfg, spacing, false);
  again.timing.insert(again.timing.begin(), {"spacing", std::chrono::duration<double>(first_try).count()});
  return again;
}

// Signs that neighbouring triangles are wound opposite ways: their normals cancel in the
// sums (eq. 1-3), so leaves straddling a change of winding look like sharp folds, and an
// inverted part's normals point 180° away from the rest, which reads as a surface that
// wraps round. Then the winding is worth checking (orient_triangles.h); a consistent mesh
// never shows the first two, and a wrapped panel's check costs little beside its charts.
bool winding_suspect(const LinearOctree& tree, double noise_floor_sigma, const Charts& charts) {
  if (noise_floor_sigma > kWindingNoiseFloor || charts.axes.size() > 1) return true;
  std::size_t opposed = 0;
  const auto& leaves = tree.leaves();
#pragma omp parallel for reduction(+ : opposed) schedule(static)
  for (std::size_t i = 0; i < leaves.size(); ++i)
    opposed += leaves[i].count >= 2 && leaves[i].sum_an.norm() < kOpposedLeafMeanNormal * leaves[i].area;
  return static_cast<double>(opposed) > kOpposedLeafShare * static_cast<double>(leaves.size());
}

// detect() on samples 'spacing' apart. remeasure: when a background is found, measure
// the spacing again on the panel alone and start over if it differs. check_winding: when
// the octree shows signs of triangles wound opposite ways, rewind them and start over.
Detection detect_at_spacing(const ingest::MeshView& input, const DetectConfig& cfg, double spacing,
                            bool remeasure, bool check_winding) {
  const auto start = Clock::now();
  Detection out;
  auto t0 = Clock::now();
  auto lap = [&](const char* stage) {
    const auto now = Clock::now();
    out.timing.emplace_back(stage, std::chrono::duration<double>(now - t0).count());
    t0 = now;
  };
  DetectionStats& st = out.stats;
  st.vertices = input.vertex_count();
  st.triangles = input.triangle_count();
  st.spacing = spacing;
  const double h = std::max(cfg.finest_node_size, 2.0 * st.spacing);
  st.leaf_size = h;
  // A stray point far off the panel (hundreds of metres) would need an octree deeper than
  // its 16 levels at this node size: such a scan is inspected cropped to the panel.
  ingest::MeshView mesh = input;
  ingest::Mesh cropped;
  {
    const Box all = bounding_box(input);
    if (static_cast<double>((all.hi - all.lo).maxCoeff()) + h > std::ldexp(h, LinearOctree::kMaxDepth)) {
      cropped = crop(input, panel_box(input), st.stray_triangles);
      mesh = cropped;
    } else {
      mesh.set_bounds(all.lo, all.hi);  // (measured once: the octree needs them too)
    }
  }

  // --- Linear octree, eq. (1)-(3) ---
  // Released once the map is built: later stages reuse its memory.
  auto tree_ptr = std::make_unique<const LinearOctree>(LinearOctree::build(mesh, h));
  const LinearOctree& tree = *tree_ptr;
  st.depth = tree.depth();
  st.leaves = tree.leaves().size();
  lap("octree");
  // The surface's area, and the leaves' normal spread (eq. 3): its median and robust
  // spread over every stride-th leaf with 4 triangles or more. Side by side (serial sums).
  const auto sum_area = [&] {
    for (const auto& l : tree.leaves()) st.surface_area += l.area;
  };
  const auto measure_noise_floor = [&] {
    const std::size_t stride = std::max<std::size_t>(1, tree.leaves().size() / 100000);
    std::vector<double> sig;
    for (std::size_t l = 0; l < tree.leaves().size(); l += stride)
      if (tree.leaves()[l].count >= 4) sig.push_back(tree.stats(l, l + 1).sigma);
    st.noise_floor_sigma = median_of(sig);
    for (auto& x : sig) x = std::abs(x - st.noise_floor_sigma);
    st.noise_floor_spread = robust_sigma(std::move(sig));
  };
  detail::side_by_side(sum_area, measure_noise_floor);
  // The leaf threshold: a feature of feature_angle's spread seen through the noise
  // (sqrt(noise_floor² + feature_angle²)), and never within the noise's own tail. A leaf
  // of a dozen noisy normals scatters about the floor by ~40 % of it: at twice the target
  // noise the first term alone was 1.8 times the floor and flagged 3 % of the leaves
  // (30 k on a door, 19 k groups, 17 k findings, 4 s).
  st.leaf_sigma_threshold = std::max(std::hypot(st.noise_floor_sigma, cfg.feature_angle),
                                     st.noise_floor_sigma + kLeafNoiseTail * st.noise_floor_spread);
  const Charts charts = find_charts(tree, st.noise_floor_sigma);
  st.charts = std::max<std::size_t>(1, charts.axes.size());
  if (check_winding && winding_suspect(tree, st.noise_floor_sigma, charts)) {
    std::optional<ingest::OrientedMesh> oriented;
    if (ingest::has_opposed_neighbours(input) ||
        ingest::large_parts(input, std::max<std::size_t>(kLargePart, input.triangle_count() / 100)) > 1) {
      oriented = ingest::orient_consistently(input);
    }
    if (oriented) {
      // Detected again on the rewound mesh; the first try shows as "winding".
      tree_ptr.reset();
      const auto first_try = Clock::now() - start;
      Detection again = detect_at_spacing(oriented->mesh, cfg, spacing, remeasure);
      again.stats.rewound_triangles = oriented->flipped;
      again.timing.insert(again.timing.begin(),
                          {"winding", std::chrono::duration<double>(first_try).count()});
      return again;
    }
    lap("winding");
  }
  if (charts.axes.size() <= 1)
    return inspect(input, mesh, std::move(tree_ptr), cfg, std::move(out), remeasure, start, t0);
  // The whole scan's map: its background (each chart's map sees only part of it), and
  // the way it looks, along or against the triangles' normals (towards the sensor), which
  // every chart's map takes: a dent on a side turned away from the sensor stays a dent.
  int facing = 1;
  {
    std::vector<std::uint8_t> background_leaf;
    const HeightMap whole = build_height_map(tree, h, cfg.hole_depth, &background_leaf);
    if (remeasure && !background_leaf.empty())
      if (const double on_panel = panel_spacing_if_other(mesh, tree, background_leaf, cfg, h);
          on_panel > 0.0) {
        tree_ptr.reset();
        return start_over(input, cfg, on_panel, start);
      }
    Eigen::Vector3d sum_an = Eigen::Vector3d::Zero();
    for (const OctreeLeaf& l : tree.leaves()) sum_an += l.sum_an.cast<double>();
    if (whole.axes.row(2).dot(sum_an) < 0.0) facing = -1;
  }
  return inspect_charts(input, mesh, std::move(tree_ptr), charts, facing, cfg, std::move(out));
}

// --- The stages of inspect, in order ---

// Features (eq. 3-4): the octree's feature leaves, grouped. Coarse nodes dilute a small
// feature's spread by its share of the node's area, so they are split at half the leaf
// threshold (the paper's single threshold misses 1 cm features in 10 cm nodes on dense,
// noisy scans). Counts them in st.
std::vector<std::vector<std::uint32_t>> feature_groups(const LinearOctree& tree, const DetectConfig& cfg,
                                                       DetectionStats& st) {
  const double leaf_sigma = st.leaf_sigma_threshold;
  const std::vector<std::uint32_t> feature = tree.feature_leaves(0.5 * leaf_sigma, leaf_sigma);
  auto groups = group_features(tree, feature, cfg.min_occupancy);
  st.feature_leaves = feature.size();
  st.feature_groups = groups.size();
  return groups;
}

// Candidates: connected pixels over the deviation test, in an eq. (3)-(4) feature group,
// or on one of the reference's fold lines (a character line's rounding, which the fits
// from either side leave: reference_surface.h), so that the line is one design feature;
// none in a hole's zone. With the masks the measurement leaves out.
struct CandidateSet {
  cv::Mat fold_px;               // CV_8U: the fold lines' pixels
  cv::Mat not_surface;           // CV_8U: left out of the normals' plane fits (candidates, spikes)
  cv::Mat not_ring;              // CV_8U: ... and of the local references (also borders, holes)
  cv::Mat labels;                // CV_32S: component number per pixel, 0 for none
  std::vector<Candidate> comps;  // index 0 is the background
};

CandidateSet find_candidates(const HeightMap& map, const ReferenceSurface& reference,
                             const Deviation& deviation, const std::vector<long>& group_pixels,
                             const cv::Mat& edge_zone, const cv::Mat& hole_zone) {
  const int rows = map.rows, cols = map.cols;
  CandidateSet s;
  cv::Mat octree_px(rows, cols, CV_8U, cv::Scalar(0));
  for (const long k : group_pixels) octree_px.data[k] = 255;
  octree_px &= ~hole_zone;
  s.fold_px = cv::Mat(rows, cols, CV_8U, cv::Scalar(0));
  if (const auto& folds = reference.fold_lines(); !folds.empty()) {
#pragma omp parallel for schedule(static)
    for (std::int64_t k = 0; k < static_cast<std::int64_t>(map.size()); ++k)
      if (folds[static_cast<std::size_t>(k)] && !hole_zone.data[k])
        octree_px.data[k] = s.fold_px.data[k] = 255;
  }
  const cv::Mat any = deviation.candidates | octree_px;
  s.not_surface = any | deviation.spikes;
  s.not_ring = s.not_surface | edge_zone | hole_zone;
  s.comps = candidate_components(any, deviation.candidates, map, edge_zone, s.labels);
  return s;
}

// Why a candidate is a design feature: by its shape (design_rules.h) or as a piece next
// to one; nullptr when it is neither.
struct DesignTest {
  const DetectConfig& cfg;
  const cv::Mat& near_design;  // CV_8U: near_design_zone
  const cv::Mat& dev;          // CV_32F: deviation along the normal (m)
  const char* operator()(const Candidate& comp) const {
    if (const char* why = design_reason(comp.shape, cfg)) return why;
    return next_to_design(comp.pixels, near_design, dev) ? "next to a design feature" : nullptr;
  }
};

// Measurement: each dent and bump candidate measured against a local reference fitted
// around it (measure_candidate.h), and its normal from a least-squares plane over a
// normal_patch square around it, leaving out the candidate itself; side by side (they
// only read the scene). Entry ci is candidate ci's; design features' stay empty.
void measure_candidates(const CandidateScene& scene, const std::vector<Candidate>& comps,
                        const DesignTest& is_design, const cv::Mat& not_surface, const DetectConfig& cfg,
                        std::vector<Measurement>& measured, std::vector<Eigen::Vector3d>& normals) {
  const HeightMap& map = scene.map;
  const int cols = map.cols;
  const int ncomp = static_cast<int>(comps.size());
  measured.assign(comps.size(), {});
  normals.assign(comps.size(), Eigen::Vector3d::Zero());
#pragma omp parallel for schedule(dynamic, 1)
  for (int ci = 1; ci < ncomp; ++ci) {
    const Candidate& comp = comps[static_cast<std::size_t>(ci)];
    if (comp.pixels.empty() || is_design(comp)) continue;
    const Measurement& m = measured[static_cast<std::size_t>(ci)] =
        measure_candidate(scene, comp.pixels, ci, comp.shape.length, comp.shape.mean);
    const long pk = map.pixel_of(m.position.x(), m.position.y());
    normals[static_cast<std::size_t>(ci)] =
        patch_normal(map, cfg.normal_patch, pk >= 0 ? static_cast<int>(pk / cols) : m.peak / cols,
                     pk >= 0 ? static_cast<int>(pk % cols) : m.peak % cols, not_surface);
  }
}

// Classification: every candidate into out, a design feature (out.features) or, by
// classify_candidate, a dent or bump (out.defects) or noise (out.features), its pixels
// labelled in out.labels (defects: their index; features: feature_label(index)). A candidate
// of the octree's alone (its normals vary, the deviation test saw nothing) on an outlier
// spike's pixels is that spike's: its triangles' normals, and the trace its steep sides
// leave on the smoothed map (a 35 um "bump" beside a cluster of three outliers, 3 mm
// apart, at 3 in 1000). sigma3: the deviation noise at the finest scale.
void classify_candidates(const std::vector<Candidate>& comps, const std::vector<Measurement>& measured,
                         const std::vector<Eigen::Vector3d>& normals, const DesignTest& is_design,
                         const cv::Mat& spike, double sigma3, const DetectConfig& cfg, Detection& out) {
  const HeightMap& map = out.map;
  const auto touches_spike = [&](const std::vector<std::int32_t>& pixels) {
    return std::any_of(pixels.begin(), pixels.end(), [&](std::int32_t k) { return spike.data[k] != 0; });
  };
  for (std::size_t ci = 1; ci < comps.size(); ++ci) {
    const Candidate& comp = comps[ci];
    if (comp.pixels.empty()) continue;
    const CandidateShape& shape = comp.shape;
    if (const char* why = is_design(comp)) {
      for (auto k : comp.pixels) out.labels[static_cast<std::size_t>(k)] = feature_label(out.features.size());
      out.features.push_back(design_finding(comp, map, out.deviation, why));
      continue;
    }
    const bool outlier =
        !comp.has_deviation &&
        (shape.length < std::max(cfg.min_diameter, 2.5 * out.stats.spacing) || touches_spike(comp.pixels));
    Finding f = classify_candidate(comp, measured[ci], normals[ci], map, cfg, sigma3, outlier);
    protocol::Defect& d = f.defect;
    const bool is_defect =
        d.defect_class == protocol::DefectClass::kDent || d.defect_class == protocol::DefectClass::kBump;
    const int label =
        is_defect ? static_cast<std::int32_t>(out.defects.size()) : feature_label(out.features.size());
    for (auto k : comp.pixels) out.labels[static_cast<std::size_t>(k)] = label;
    d.id = static_cast<std::uint32_t>(is_defect ? out.defects.size() : out.features.size());
    (is_defect ? out.defects : out.features).push_back(std::move(f));
  }
}

// Along features: defects on and beside design features, out of the feature's profile
// along it (along_feature.h), appended to out.defects with their pixels labelled.
void add_along_feature_defects(const CandidateSet& cs, const DesignTest& is_design,
                               const Deviation& deviation, const cv::Mat& edge_zone, const cv::Mat& hole_zone,
                               const std::vector<int>& scales, double sigma3, const DetectConfig& cfg,
                               Detection& out) {
  const HeightMap& map = out.map;
  cv::Mat design_px(map.rows, map.cols, CV_8U, cv::Scalar(0));
  for (const Candidate& comp : cs.comps)
    if (!comp.pixels.empty() && is_design(comp))
      for (auto k : comp.pixels) design_px.data[k] = 255;
  design_px |= cs.fold_px;
  // The median test's spikes only: grown over clusters too, they left more pixels along
  // lines without a height, whose profiles then read as 30-70 um specks (5 false alarms
  // more over 40 doors with character lines).
  const cv::Mat excluded = deviation.median_spikes | hole_zone;
  std::vector<std::vector<std::int32_t>> along_px;
  const AlongFeatureScene along_scene{
      map,    deviation.along_normal, design_px, edge_zone, excluded, cs.not_surface, out.labels,
      scales, deviation.scale_sigma,  sigma3};
  std::vector<Finding> along = defects_along_features(along_scene, cfg, along_px);
  for (std::size_t i = 0; i < along.size(); ++i) {
    const int label = static_cast<int>(out.defects.size());
    for (auto k : along_px[i]) out.labels[static_cast<std::size_t>(k)] = label;
    along[i].defect.id = static_cast<std::uint32_t>(label);
    out.defects.push_back(std::move(along[i]));
  }
}

// Coarse scans (kCoarseSpacing): the dents and bumps of the map are replaced by those of
// the vertices, coherent groups standing out of their neighbours' robust local surface
// (local_surface_fit.h, coarse_defects.h). No group may touch a map candidate larger
// than any defect (a handle), a fold line or a hole (widened by a pixel), or come within
// kCoarseBorderRings edges of the mesh's boundary; the map's features stay as they are.
void replace_with_vertex_defects(const ingest::MeshView& mesh, const CandidateSet& cs,
                                 const cv::Mat& hole_zone, const DetectConfig& cfg, Detection& out) {
  const HeightMap& map = out.map;
  const double spacing = out.stats.spacing;
  cv::Mat zone = hole_zone | cs.fold_px;
  // A pixel is two spacings: one a steep defect leaves empty makes the map's border zone,
  // and three of a defect in a row are "long and thin" by shape. Only candidates too large
  // for a defect count here, and the border is the mesh's own (near_mesh_boundary).
  for (const Candidate& comp : cs.comps)
    if (!comp.pixels.empty() && comp.shape.length > cfg.max_defect_diameter)
      for (auto k : comp.pixels) zone.data[k] = 255;
  dilate_in_strips(zone, zone, cv::getStructuringElement(cv::MORPH_RECT, {3, 3}));

  const std::size_t n = mesh.vertex_count();
  std::vector<Eigen::Vector3f> points(n, Eigen::Vector3f::Constant(std::numeric_limits<float>::quiet_NaN()));
  std::vector<std::int32_t> pixel(n, -1);
  std::vector<std::uint8_t> excluded = near_mesh_boundary(mesh, kCoarseBorderRings);
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < static_cast<std::int64_t>(n); ++i) {
    const auto vi = static_cast<std::size_t>(i);
    const Eigen::Vector3d q = map.to_map(mesh.vertex(vi).cast<double>());
    const long k = map.pixel_of(q.x(), q.y());
    if (k < 0 || !(map.weight[static_cast<std::size_t>(k)] > 0.0f)) {
      excluded[vi] = 1;
      continue;
    }
    points[vi] = q.cast<float>();
    pixel[vi] = static_cast<std::int32_t>(k);
    excluded[vi] |= zone.data[k];
  }
  LocalFitOptions fit;
  fit.inner_radius = kCoarseInner * spacing;
  fit.outer_radius = kCoarseOuter * spacing;
  const std::vector<float> residual = local_surface_residuals(points, fit);
  std::vector<double> magnitudes;
  for (std::size_t i = 0; i < n; ++i)
    if (!excluded[i] && std::isfinite(residual[i])) magnitudes.push_back(std::abs(residual[i]));
  if (magnitudes.empty()) return;
  const double sigma = std::max(robust_sigma(std::move(magnitudes)), 1e-9);

  // The map's dents and bumps give way; their pixels are unlabelled.
  out.defects.clear();
  for (auto& l : out.labels)
    if (l >= 0) l = kNoFinding;
  for (const VertexGroup& g :
       coherent_groups(mesh, residual, excluded, sigma, cfg.detection_sigma, kCoarseMember)) {
    const std::int32_t k = pixel[g.apex];
    const Eigen::Vector3d normal =
        patch_normal(map, cfg.normal_patch, k / map.cols, k % map.cols, cs.not_surface);
    Finding f = coarse_finding(g, mesh, residual, normal, spacing, sigma, cfg.detection_sigma);
    if (std::abs(f.defect.height) < cfg.min_height) continue;
    const int label = static_cast<int>(out.defects.size());
    for (const std::uint32_t v : g.vertices) {
      out.labels[static_cast<std::size_t>(pixel[v])] = label;
      ++f.pixels;
    }
    f.defect.id = static_cast<std::uint32_t>(label);
    out.defects.push_back(std::move(f));
  }
}

// Holes: each a defect (hole_finding), appended to out.defects with its pixels labelled.
void add_hole_defects(const std::vector<HoleRegion>& holes, const std::vector<float>& ref,
                      const cv::Mat& hole_zone, const DetectConfig& cfg, Detection& out) {
  for (const HoleRegion& hr : holes) {
    Finding f = hole_finding(hr, out.map, ref, hole_zone, cfg.normal_patch);
    f.defect.id = static_cast<std::uint32_t>(out.defects.size());
    for (auto k : hr.pixels) out.labels[static_cast<std::size_t>(k)] = static_cast<int>(out.defects.size());
    out.defects.push_back(std::move(f));
  }
}

// The stages after the octree, on one tree: the whole scan's, or a chart's: features,
// height map, reference and deviation, holes, candidates, measurement, classification,
// along features; each stage's time in out.timing. remeasure: as detect_at_spacing's;
// chart_w: build_height_map's.
Detection inspect(const ingest::MeshView& input, const ingest::MeshView& mesh,
                  std::unique_ptr<const LinearOctree> tree_ptr, const DetectConfig& cfg, Detection out,
                  bool remeasure, Clock::time_point start, Clock::time_point t0,
                  const Eigen::Vector3d& chart_w) {
  auto lap = [&](const char* stage) {
    const auto now = Clock::now();
    out.timing.emplace_back(stage, std::chrono::duration<double>(now - t0).count());
    t0 = now;
  };
  const LinearOctree& tree = *tree_ptr;
  DetectionStats& st = out.stats;
  const double h = st.leaf_size;
  const auto groups = feature_groups(tree, cfg, st);
  lap("features");

  std::vector<std::uint8_t> background_leaf;
  out.map = build_height_map(tree, h, cfg.hole_depth, &background_leaf, chart_w);
  st.background_area = out.map.background_area;
  if (remeasure && !background_leaf.empty()) {
    if (const double on_panel = panel_spacing_if_other(mesh, tree, background_leaf, cfg, h); on_panel > 0.0) {
      background_leaf = {};
      tree_ptr.reset();
      out.map = {};
      return start_over(input, cfg, on_panel, start);
    }
  }
  lap("map");
  const HeightMap& map = out.map;
  // The feature groups' pixels (eq. 3-4 candidates); the leaves are not needed after this.
  const std::vector<long> group_pixels = pixels_of_groups(tree, groups, map);
  // Working memory: the octree's leaves and the records of its build; the map's arrays and
  // deviation images; the map's build (per leaf: pixel; per pixel: front).
  st.working_bytes =
      tree.bytes() + map.size() * (6 * 4 + 4 * 4 + 8) + tree.leaves().size() * 4 + map.size() * 4;
  tree_ptr.reset();

  const bool on_chart = chart_w.squaredNorm() > 0.0;
  const cv::Mat edge_zone = border_zone(map);
  const std::vector<int> scales = detection_scales(h);
  ReferenceSurface reference(map, cfg.reference_window);
  reference.look_for_folds(!on_chart);  // not on a chart (reference_surface.h)
  Deviation deviation =
      deviation_from_reference(map, reference, interior_of(map, edge_zone), scales, cfg, on_chart);
  st.deviation_noise = deviation.noise;
  lap("reference");
  const std::vector<float>& ref = reference.heights();

  const std::vector<HoleRegion> holes =
      find_holes(map, deviation.along_normal, ref, cfg.hole_depth, cfg.max_hole_diameter);
  const cv::Mat hole_zone = hole_zone_of(holes, map.rows, map.cols, h);
  deviation.candidates &= ~hole_zone;

  const CandidateSet cs = find_candidates(map, reference, deviation, group_pixels, edge_zone, hole_zone);
  const cv::Mat& dev = deviation.along_normal;
  detail::side_by_side([&] { out.labels.assign(map.size(), -1); },
                       [&] { out.deviation.assign(dev.ptr<float>(), dev.ptr<float>() + map.size()); });
  const double sigma3 = std::max(deviation.scale_sigma.front(), 1e-9);
  const cv::Mat near_design = near_design_zone(cs.comps, cs.fold_px, edge_zone, map, cfg);
  const DesignTest is_design{cfg, near_design, dev};

  // The scan's own samples under the dent and bump candidates, for their apex depth.
  // Design features need none.
  const bool coarse = scales.front() < 3;
  std::vector<const Candidate*> measurable;
  for (const Candidate& comp : cs.comps)
    if (!comp.pixels.empty() && !is_design(comp)) measurable.push_back(&comp);
  const PixelSamples samples = samples_around(mesh, map, measurable);
  lap("samples");

  const CandidateScene scene{mesh,           map,
                             reference,      ref,
                             cs.not_ring,    deviation.spikes,
                             cs.labels,      samples,
                             st.spacing,     st.deviation_noise,
                             cfg.min_height, coarse};
  std::vector<Measurement> measured;
  std::vector<Eigen::Vector3d> normals;
  measure_candidates(scene, cs.comps, is_design, cs.not_surface, cfg, measured, normals);
  classify_candidates(cs.comps, measured, normals, is_design, deviation.spikes, sigma3, cfg, out);
  if (st.spacing >= kCoarseSpacing) {
    replace_with_vertex_defects(mesh, cs, hole_zone, cfg, out);
    lap("coarse vertices");
  }
  if (cfg.along_features && !coarse) {
    add_along_feature_defects(cs, is_design, deviation, edge_zone, hole_zone, scales, sigma3, cfg, out);
    lap("along features");
  }
  add_hole_defects(holes, ref, hole_zone, cfg, out);
  order_findings(out);
  lap("classify");
  return out;
}

// Each chart inspected as a scan of its own, its map looking along (facing +1) or
// against (-1) the triangles' normals as the whole scan's does; a finding is kept from
// the chart that owns the surface where it lies, and each chart's map keeps the labels
// of what it owns. The largest chart's map is the detection's own.
Detection inspect_charts(const ingest::MeshView& input, const ingest::MeshView& mesh,
                         std::unique_ptr<const LinearOctree> tree_ptr, const Charts& charts, int facing,
                         const DetectConfig& cfg, Detection out) {
  const LinearOctree& tree = *tree_ptr;
  const std::size_t n = charts.axes.size();
  std::vector<Detection> parts;
  for (std::size_t c = 0; c < n; ++c) {
    Detection part;
    part.stats = out.stats;
    auto chart_tree =
        std::make_unique<const LinearOctree>(tree.subset(charts.members(tree, static_cast<int>(c))));
    parts.push_back(inspect(input, mesh, std::move(chart_tree), cfg, std::move(part), false, Clock::now(),
                            Clock::now(), facing * charts.axes[c]));
  }
  std::size_t main = 0, most = 0;
  for (std::size_t c = 0; c < n; ++c) {
    const auto& w = parts[c].map.weight;
    const auto pixels =
        static_cast<std::size_t>(std::count_if(w.begin(), w.end(), [](float x) { return x > 0.0f; }));
    if (pixels > most) most = pixels, main = c;
  }
  // Stages: the scan's so far, then each later stage summed over the charts.
  for (std::size_t c = 0; c < n; ++c)
    for (const auto& [stage, seconds] : parts[c].timing) {
      auto it =
          std::find_if(out.timing.begin(), out.timing.end(), [&](const auto& t) { return t.first == stage; });
      if (it == out.timing.end())
        out.timing.emplace_back(stage, seconds);
      else
        it->second += seconds;
    }
  out.stats.deviation_noise = parts[main].stats.deviation_noise;
  out.stats.background_area = parts[main].stats.background_area;
  out.stats.working_bytes = parts[main].stats.working_bytes;
  out.stats.feature_leaves = out.stats.feature_groups = 0;
  // The findings each chart owns, and its labels renumbered into the merged lists (the
  // main chart first: its findings lead before order_findings sorts them).
  std::vector<std::size_t> order{main};
  for (std::size_t c = 0; c < n; ++c)
    if (c != main) order.push_back(c);
  for (const std::size_t c : order) {
    Detection& part = parts[c];
    out.stats.feature_leaves += part.stats.feature_leaves;
    out.stats.feature_groups += part.stats.feature_groups;
    const auto owned = [&](const Finding& f) {
      return charts.owner(tree, f.defect.position) == static_cast<int>(c);
    };
    std::vector<std::int32_t> defect_at, feature_at;  // index in the merged lists, or -1
    for (Finding& f : part.defects) {
      defect_at.push_back(owned(f) ? static_cast<std::int32_t>(out.defects.size()) : -1);
      if (defect_at.back() < 0) continue;
      f.defect.id = static_cast<std::uint32_t>(out.defects.size());  // order_findings' pre-sort index
      out.defects.push_back(std::move(f));
    }
    for (Finding& f : part.features) {
      feature_at.push_back(owned(f) ? static_cast<std::int32_t>(out.features.size()) : -1);
      if (feature_at.back() >= 0) out.features.push_back(std::move(f));
    }
    for (auto& l : part.labels) {
      if (l >= 0) {
        l = defect_at[static_cast<std::size_t>(l)];
      } else if (is_feature_label(l)) {
        const std::int32_t kept = feature_at[feature_index(l)];
        l = kept >= 0 ? feature_label(static_cast<std::size_t>(kept)) : kNoFinding;
      }
    }
    ChartMap chart{std::move(part.map), std::move(part.deviation), std::move(part.labels)};
    if (c == main) {
      out.map = std::move(chart.map);
      out.deviation = std::move(chart.deviation);
      out.labels = std::move(chart.labels);
    } else {
      out.more_charts.push_back(std::move(chart));
    }
  }
  order_findings(out);
  return out;
}

}  // namespace

Detection detect(const ingest::MeshView& input, const DetectConfig& cfg) {
  return detect(input, cfg, ingest::point_spacing(input));
}

Detection detect(const ingest::MeshView& input, const DetectConfig& cfg, double point_spacing) {
  return detect_at_spacing(input, cfg, point_spacing, true, true);
}

}  // namespace dentmark::detect
