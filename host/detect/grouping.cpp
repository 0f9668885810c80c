#include "dentmark/host/detect/grouping.h"

#include <algorithm>
#include <numeric>
#include <unordered_map>

namespace dentmark::detect {
namespace {

struct UnionFind {
  std::vector<std::uint32_t> parent;
  explicit UnionFind(std::size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0u); }
  std::uint32_t find(std::uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  }
  void unite(std::uint32_t a, std::uint32_t b) {
    a = find(a), b = find(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  }
};

}  // namespace

double relative_occupancy(const LinearOctree& tree, const OctreeLeaf& leaf) {
  const double h = tree.leaf_size();
  return leaf.area / (h * h * h);  // eq. (4)
}

std::vector<std::vector<std::uint32_t>> group_features(const LinearOctree& tree,
                                                       const std::vector<std::uint32_t>& feature_leaves,
                                                       double min_occupancy) {
  const auto& leaves = tree.leaves();
  std::vector<std::uint32_t> kept;
  kept.reserve(feature_leaves.size());
  for (auto l : feature_leaves)
    if (relative_occupancy(tree, leaves[l]) * tree.leaf_size() >= min_occupancy) kept.push_back(l);
  std::sort(kept.begin(), kept.end(), [&](auto a, auto b) { return leaves[a].key < leaves[b].key; });
  std::vector<std::uint64_t> keys(kept.size());
  for (std::size_t i = 0; i < kept.size(); ++i) keys[i] = leaves[kept[i]].key;
  UnionFind uf(kept.size());
  const int cells = 1 << tree.depth();
  for (std::size_t i = 0; i < kept.size(); ++i) {
    const Eigen::Vector3i c = LinearOctree::decode(keys[i]);
    // 26-adjacency: the 13 neighbours "after" this cell suffice, the rest are symmetric.
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          if (dz < 0 || (dz == 0 && (dy < 0 || (dy == 0 && dx <= 0)))) continue;
          const Eigen::Vector3i q = c + Eigen::Vector3i(dx, dy, dz);
          if ((q.array() < 0).any() || (q.array() >= cells).any()) continue;
          const std::uint64_t k = LinearOctree::encode(q);
          const auto it = std::lower_bound(keys.begin(), keys.end(), k);
          if (it != keys.end() && *it == k)
            uf.unite(static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(it - keys.begin()));
        }
  }
  std::unordered_map<std::uint32_t, std::size_t> slot;
  std::vector<std::vector<std::uint32_t>> groups;
  for (std::size_t i = 0; i < kept.size(); ++i) {
    const auto r = uf.find(static_cast<std::uint32_t>(i));
    auto [it, inserted] = slot.try_emplace(r, groups.size());
    if (inserted) groups.emplace_back();
    groups[it->second].push_back(kept[i]);
  }
  return groups;
}

}  // namespace dentmark::detect
