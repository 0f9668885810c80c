#pragma once
// Charts: a scan that wraps round (a fender, a bumper's corner, a merged multi-view scan)
// is no height field over one plane. Its steep sides project onto thin strips of the map,
// where a 20 mm dent spans two pixels and the whole side reads as one long border feature.
// Such a scan is inspected in charts: regions whose surface turns at most ~30° from the
// chart's axis, each seen as its own height map, with a margin of its neighbours' surface
// around it so that no defect near a chart's edge lies on an artificial border. A finding
// belongs to the chart whose axis is closest to the surface normal where it lies.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "dentmark/host/detect/linear_octree.h"

namespace dentmark::detect {

struct Charts {
  std::vector<Eigen::Vector3d> axes;  // unit, scan frame; one axis: no charts needed
  // Coarse nodes (key at the finest depth >> node_shift) in key order, with the chart
  // each belongs to.
  int node_shift = 0;
  std::vector<std::uint64_t> node_keys;
  std::vector<std::uint8_t> node_chart;
  std::vector<Eigen::Vector3f> node_normals;  // unit

  // The chart owning the surface at p (scan frame, m): its coarse node's, or, off the
  // surface, the nearest node's along the key order; -1 if there are no nodes.
  int owner(const LinearOctree& tree, const Eigen::Vector3d& p) const;
  // Per leaf, 1 if it is in chart c (its coarse node's normal within the chart's reach).
  std::vector<std::uint8_t> members(const LinearOctree& tree, int c) const;
};

// The charts for the tree's surface: one axis when less than 3 % of the surface (smooth
// panel, not a handle's walls) turns more than 45° from the mean normal (a door, a hood:
// one map), else up to 6 axes found by area-weighted spherical k-means over coarse
// nodes' normals. noise_sigma: the leaves' normal spread from noise alone (eq. 3's σ, the
// scan's noise floor).
Charts find_charts(const LinearOctree& tree, double noise_sigma);

}  // namespace dentmark::detect
