#pragma once
// The detection pipeline (design.md §3): triangles -> linear octree (eq. 1-3) ->
// feature groups (eq. 4) and deviation from a robust reference surface -> candidates ->
// classes (dent, bump, design_feature, noise) with position, 30 x 30 mm normal,
// diameter, signed height, area and score.

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "dentmark/common/ingest/mesh_view.h"
#include "dentmark/common/protocol/messages.h"
#include "dentmark/host/detect/config.h"
#include "dentmark/host/detect/height_map.h"

namespace dentmark::detect {

struct DetectionStats {
  std::size_t vertices = 0, triangles = 0;
  double surface_area = 0.0;          // m²
  double spacing = 0.0;               // m, median edge length
  double leaf_size = 0.0;             // m, finest node edge used
  int depth = 0;                      // octree depth
  std::size_t leaves = 0;             // occupied finest nodes
  double noise_floor_sigma = 0.0;     // median leaf normal spread (eq. 3)
  double noise_floor_spread = 0.0;    // its robust sigma (1.4826 MAD) over the leaves
  double leaf_sigma_threshold = 0.0;  // a feature leaf's spread exceeds this (eq. 3)
  std::size_t feature_leaves = 0, feature_groups = 0;
  double deviation_noise = 0.0;       // m, robust sigma of the per-pixel deviation
  std::size_t working_bytes = 0;      // memory beyond the mesh
  std::size_t stray_triangles = 0;    // left out: reaching stray points far off the panel
  double background_area = 0.0;       // m² of the map taken off: a wall or floor behind the panel
  std::size_t charts = 1;             // height maps the surface was inspected in (charts.h)
  std::size_t rewound_triangles = 0;  // wound against their neighbours: rewound (orient_triangles.h)
};

struct Finding {
  protocol::Defect defect;
  std::string reason;  // why this class (for people)
  int pixels = 0;
};

// A map pixel's label: the index of the defect that owns it (>= 0), the index of the
// feature that owns it encoded by feature_label (<= -2), or kNoFinding.
inline constexpr std::int32_t kNoFinding = -1;
constexpr std::int32_t feature_label(std::size_t index) {
  return -2 - static_cast<std::int32_t>(index);
}
constexpr bool is_feature_label(std::int32_t label) {
  return label <= -2;
}
constexpr std::size_t feature_index(std::int32_t label) {
  return static_cast<std::size_t>(-2 - label);
}

// A height map as the pictures show it.
struct ChartMap {
  HeightMap map;
  std::vector<float> deviation;      // per pixel, m along the normal (NaN: none)
  std::vector<std::int32_t> labels;  // per pixel: see feature_label
};

struct Detection {
  std::vector<Finding> defects;   // dent, bump, hole
  std::vector<Finding> features;  // design_feature, noise
  DetectionStats stats;
  std::vector<std::pair<std::string, double>> timing;  // stage, seconds
  // The scan's height map (a scan inspected in charts: its largest chart's).
  HeightMap map;
  std::vector<float> deviation;      // per pixel, m along the normal (NaN: none)
  std::vector<std::int32_t> labels;  // per pixel: see feature_label
  // The other charts' maps (charts.h), each labelled with the findings it owns.
  std::vector<ChartMap> more_charts;
};

Detection detect(const ingest::MeshView& mesh, const DetectConfig& config);
// The same, with the scan's point spacing already measured (ingest::point_spacing of this
// very mesh, as measure_scale gives it): not sampled a second time.
Detection detect(const ingest::MeshView& mesh, const DetectConfig& config, double point_spacing);

}  // namespace dentmark::detect
