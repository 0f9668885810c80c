#pragma once
// Feature grouping (paper §III-B): finest-depth feature leaves whose relative occupancy
// ρ = Σ a_i / v (eq. 4) is too low are outliers and dropped; the rest join groups by
// 26-adjacency (union-find).

#include <cstdint>
#include <vector>

#include "dentmark/host/detect/linear_octree.h"

namespace dentmark::detect {

// Relative occupancy of a leaf, eq. (4): area over node volume (1/m).
double relative_occupancy(const LinearOctree& tree, const OctreeLeaf& leaf);

// Groups of leaf indices. min_occupancy is ρ·(leaf edge), i.e. area over face area.
std::vector<std::vector<std::uint32_t>> group_features(const LinearOctree& tree,
                                                       const std::vector<std::uint32_t>& feature_leaves,
                                                       double min_occupancy);

}  // namespace dentmark::detect
