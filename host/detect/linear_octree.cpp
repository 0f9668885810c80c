#include "dentmark/host/detect/linear_octree.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "leaf_sums.h"

namespace dentmark::detect {

std::uint64_t LinearOctree::triangle_key(const ingest::MeshView& mesh, std::size_t t) const {
  const detail::LeafGrid grid{origin_.cast<float>(), static_cast<float>(1.0 / leaf_size_), depth_};
  return grid.key(detail::triangle_centroid(mesh, mesh.triangle(t)));
}

LinearOctree LinearOctree::build(const ingest::MeshView& mesh, double leaf_size) {
  if (!(leaf_size > 0.0) || !std::isfinite(leaf_size))
    throw std::invalid_argument("octree leaf size must be > 0");
  if (mesh.triangle_count() == 0) throw std::invalid_argument("octree of an empty mesh");
  if (mesh.triangle_count() >= (1ull << 32)) throw std::invalid_argument("more than 4 G triangles");

  // Bounding box of the vertices (finite by ingest's contract).
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max()), hi = -lo;
#pragma omp parallel
  {
    Eigen::Vector3f l = lo, h = hi;
#pragma omp for nowait schedule(static)
    for (std::int64_t i = 0; i < static_cast<std::int64_t>(mesh.vertex_count()); ++i) {
      const Eigen::Vector3f v = mesh.vertex(static_cast<std::size_t>(i));
      if (v.allFinite()) l = l.cwiseMin(v), h = h.cwiseMax(v);
    }
#pragma omp critical
    lo = lo.cwiseMin(l), hi = hi.cwiseMax(h);
  }
  const double extent = (hi - lo).cast<double>().maxCoeff() + leaf_size;
  int depth = 1;
  while (leaf_size * std::ldexp(1.0, depth) < extent) ++depth;
  // 16 levels: 65 536 finest nodes a side (65 m at 1 mm); a bucket's cell fits 32 bits.
  if (depth > 16)
    throw std::invalid_argument("finest node too small for the scan's extent (more than 65536 nodes a side)");
  LinearOctree tree;
  tree.depth_ = depth;
  tree.leaf_size_ = leaf_size;
  tree.origin_ = lo.cast<double>() - Eigen::Vector3d::Constant(0.5 * leaf_size);
  tree.leaves_ = detail::accumulate_leaves(
      mesh, {tree.origin_.cast<float>(), static_cast<float>(1.0 / leaf_size), depth});

  const std::size_t total = tree.leaves_.size();
  tree.prefix_area_.resize(total + 1);
  tree.prefix_an_.resize(total + 1);
  tree.prefix_area_[0] = 0.0;
  tree.prefix_an_[0].setZero();
  for (std::size_t l = 0; l < total; ++l) {
    tree.prefix_area_[l + 1] = tree.prefix_area_[l] + tree.leaves_[l].area;
    tree.prefix_an_[l + 1] = tree.prefix_an_[l] + tree.leaves_[l].sum_an.cast<double>();
  }
  return tree;
}

NodeStats LinearOctree::stats(std::size_t begin, std::size_t end) const {
  NodeStats s;
  s.area = prefix_area_[end] - prefix_area_[begin];
  if (!(s.area > 0.0)) return s;
  s.mean_normal = (prefix_an_[end] - prefix_an_[begin]) / s.area;         // eq. (2)
  s.sigma = std::sqrt(std::max(0.0, 1.0 - s.mean_normal.squaredNorm()));  // eq. (3)
  return s;
}

std::vector<std::uint32_t> LinearOctree::feature_leaves(double split_sigma, double leaf_sigma) const {
  std::vector<std::uint32_t> out;
  struct Node {
    std::size_t begin, end;
    int level;
  };
  std::vector<Node> stack{{0, leaves_.size(), 0}};
  while (!stack.empty()) {
    const Node node = stack.back();
    stack.pop_back();
    if (node.begin >= node.end) continue;
    if (node.level == depth_) {
      // A leaf: one cell, one range of triangles.
      if (stats(node.begin, node.end).sigma > leaf_sigma)
        out.push_back(static_cast<std::uint32_t>(node.begin));
      continue;
    }
    if (node.level > 0 && stats(node.begin, node.end).sigma <= split_sigma) continue;
    // Children: the next three key bits; ranges found by binary search (keys sorted).
    const int shift = 3 * (depth_ - node.level - 1);
    std::size_t b = node.begin;
    std::size_t bounds[9];
    bounds[0] = node.begin;
    for (int c = 0; c < 8; ++c) {
      const auto it = std::partition_point(
          leaves_.begin() + static_cast<std::ptrdiff_t>(b),
          leaves_.begin() + static_cast<std::ptrdiff_t>(node.end),
          [&](const OctreeLeaf& l) { return static_cast<int>((l.key >> shift) & 7) <= c; });
      b = static_cast<std::size_t>(it - leaves_.begin());
      bounds[c + 1] = b;
    }
    for (int c = 7; c >= 0; --c) stack.push_back({bounds[c], bounds[c + 1], node.level + 1});
  }
  return out;
}

std::size_t LinearOctree::bytes() const {
  return leaves_.capacity() * sizeof(OctreeLeaf) + prefix_area_.capacity() * 8 +
         prefix_an_.capacity() * sizeof(Eigen::Vector3d);
}

}  // namespace dentmark::detect
