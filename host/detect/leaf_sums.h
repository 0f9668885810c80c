#pragma once
// Per-leaf sums of the paper's eq. (1)-(2) for every occupied finest octree cell, built in
// one pass over the triangles in whatever order they come (see leaf_sums.cpp).

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

#include "dentmark/common/ingest/mesh_view.h"
#include "dentmark/host/detect/linear_octree.h"

namespace dentmark::detect::detail {

// The finest level of the octree: cells of edge 1 / inv_leaf from origin, 2^depth a side.
struct LeafGrid {
  Eigen::Vector3f origin = Eigen::Vector3f::Zero();
  float inv_leaf = 1.0f;
  int depth = 1;

  // Integer cell holding p (clamped into the grid).
  Eigen::Vector3i cell(const Eigen::Vector3f& p) const {
    const Eigen::Vector3f c = (p - origin) * inv_leaf;
    const int cells = 1 << depth;
    Eigen::Vector3i q;
    for (int a = 0; a < 3; ++a) q[a] = std::clamp(static_cast<int>(c[a]), 0, cells - 1);
    return q;
  }
  // Morton key of the cell holding p.
  std::uint64_t key(const Eigen::Vector3f& p) const { return LinearOctree::encode(cell(p)); }
  Eigen::Vector3f corner(const Eigen::Vector3i& cell) const { return origin + cell.cast<float>() / inv_leaf; }
  // Lower corner of the cell with this key.
  Eigen::Vector3f corner(std::uint64_t key) const { return corner(LinearOctree::decode(key)); }
};

inline Eigen::Vector3f triangle_centroid(const ingest::MeshView& m, const std::array<std::uint32_t, 3>& t) {
  return (m.vertex(t[0]) + m.vertex(t[1]) + m.vertex(t[2])) * (1.0f / 3.0f);
}

// How a build went.
struct LeafBuildStats {
  std::size_t record_bytes = 0;        // peak memory of the records filed on the way
  std::size_t buckets_taken_over = 0;  // buckets a thread summed for a slower one (pass 2)
};

// Leaves in Morton order, with A, S = Σ a_i N_i, Σ a_i c_i and the triangle count.
OctreeLeaves accumulate_leaves(const ingest::MeshView& mesh, const LeafGrid& grid,
                               LeafBuildStats* stats = nullptr);

}  // namespace dentmark::detect::detail
