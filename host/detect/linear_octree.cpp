#include "dentmark/host/detect/linear_octree.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "radix_sort.h"

namespace dentmark::detect {
namespace {

// Spreads the low 21 bits of x to every third bit.
std::uint64_t spread3(std::uint64_t x) {
  x &= 0x1fffff;
  x = (x | x << 32) & 0x1f00000000ffffull;
  x = (x | x << 16) & 0x1f0000ff0000ffull;
  x = (x | x << 8) & 0x100f00f00f00f00full;
  x = (x | x << 4) & 0x10c30c30c30c30c3ull;
  x = (x | x << 2) & 0x1249249249249249ull;
  return x;
}

std::uint64_t compact3(std::uint64_t x) {
  x &= 0x1249249249249249ull;
  x = (x ^ (x >> 2)) & 0x10c30c30c30c30c3ull;
  x = (x ^ (x >> 4)) & 0x100f00f00f00f00full;
  x = (x ^ (x >> 8)) & 0x1f0000ff0000ffull;
  x = (x ^ (x >> 16)) & 0x1f00000000ffffull;
  x = (x ^ (x >> 32)) & 0x1fffff;
  return x;
}

}  // namespace

std::uint64_t LinearOctree::encode(const Eigen::Vector3i& c) {
  return spread3(static_cast<std::uint64_t>(c.x())) | spread3(static_cast<std::uint64_t>(c.y())) << 1 |
         spread3(static_cast<std::uint64_t>(c.z())) << 2;
}

Eigen::Vector3i LinearOctree::decode(std::uint64_t key) {
  return {static_cast<int>(compact3(key)), static_cast<int>(compact3(key >> 1)),
          static_cast<int>(compact3(key >> 2))};
}

LinearOctree LinearOctree::build(const ingest::Mesh& mesh, double leaf_size) {
  if (!(leaf_size > 0.0) || !std::isfinite(leaf_size))
    throw std::invalid_argument("octree leaf size must be > 0");
  LinearOctree tree;
  const auto& V = mesh.vertices;
  const auto& T = mesh.triangles;
  const auto n = static_cast<std::int64_t>(T.size());
  if (n == 0) throw std::invalid_argument("octree of an empty mesh");
  if (T.size() >= (1ull << 32)) throw std::invalid_argument("more than 4 G triangles");

  // Bounding box of the vertices in use (finite by ingest's contract).
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max()), hi = -lo;
#pragma omp parallel
  {
    Eigen::Vector3f l = lo, h = hi;
#pragma omp for nowait schedule(static)
    for (std::int64_t i = 0; i < static_cast<std::int64_t>(V.size()); ++i)
      if (V[i].allFinite()) l = l.cwiseMin(V[i]), h = h.cwiseMax(V[i]);
#pragma omp critical
    lo = lo.cwiseMin(l), hi = hi.cwiseMax(h);
  }
  const double extent = (hi - lo).cast<double>().maxCoeff() + leaf_size;
  int depth = 1;
  while (leaf_size * std::ldexp(1.0, depth) < extent) ++depth;
  if (depth > 21) throw std::invalid_argument("finest node too small for the scan's extent (depth > 21)");
  tree.depth_ = depth;
  tree.leaf_size_ = leaf_size;
  tree.origin_ = lo.cast<double>() - Eigen::Vector3d::Constant(0.5 * leaf_size);
  const int cells = 1 << depth;
  const float inv = static_cast<float>(1.0 / leaf_size);
  const Eigen::Vector3f org = tree.origin_.cast<float>();

  // Morton key of each centroid, packed with the triangle id into one word when the
  // bits allow (sorting 8 bytes instead of 16).
  const int key_bits = 3 * depth;
  int id_bits = 1;
  while ((1ull << id_bits) < T.size()) ++id_bits;
  std::vector<std::uint64_t> packed(T.size());
  const bool fits = key_bits + id_bits <= 64;
  std::vector<std::uint64_t> keys_only;
  if (!fits) keys_only.resize(T.size());
  // Per-triangle a_i N_i and centroid, computed in mesh order (sequential reads) so that
  // the per-leaf sums later gather one 24-byte record per triangle, whatever the order.
  struct TriangleSums {
    Eigen::Vector3f half_cross, centroid;
  };
  std::vector<TriangleSums> sums(T.size());
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < n; ++i) {
    const auto& t = T[i];
    const Eigen::Vector3f va = V[t[0]], vb = V[t[1]], vc = V[t[2]];
    // Eq. (1): a_i = |v1 x v2| / 2; a_i N_i is half the cross product itself.
    sums[i].half_cross = 0.5f * (vb - va).cross(vc - va);
    sums[i].centroid = (va + vb + vc) * (1.0f / 3.0f);
    const Eigen::Vector3f c = (sums[i].centroid - org) * inv;
    Eigen::Vector3i q;
    for (int a = 0; a < 3; ++a) q[a] = std::clamp(static_cast<int>(c[a]), 0, cells - 1);
    const std::uint64_t key = encode(q);
    if (fits)
      packed[i] = key << id_bits | static_cast<std::uint64_t>(i);
    else
      keys_only[i] = key, packed[i] = static_cast<std::uint64_t>(i);
  }
  tree.order_.resize(T.size());
  std::vector<std::uint64_t> sorted_keys;
  if (fits) {
    detail::radix_sort(packed, id_bits, key_bits);
    const std::uint64_t id_mask = (id_bits == 64) ? ~0ull : ((1ull << id_bits) - 1);
#pragma omp parallel for schedule(static)
    for (std::int64_t i = 0; i < n; ++i) tree.order_[i] = static_cast<std::uint32_t>(packed[i] & id_mask);
  } else {
    std::sort(packed.begin(), packed.end(),
              [&](std::uint64_t a, std::uint64_t b) { return keys_only[a] < keys_only[b]; });
    for (std::int64_t i = 0; i < n; ++i) tree.order_[i] = static_cast<std::uint32_t>(packed[i]);
  }
  auto key_at = [&](std::size_t i) { return fits ? packed[i] >> id_bits : keys_only[packed[i]]; };

  // Leaf boundaries, then per-leaf sums in parallel.
  std::vector<std::uint32_t> starts;
  starts.reserve(T.size() / 4 + 1);
  starts.push_back(0);
  for (std::size_t i = 1; i < T.size(); ++i)
    if (key_at(i) != key_at(i - 1)) starts.push_back(static_cast<std::uint32_t>(i));
  tree.leaves_.resize(starts.size());
  const auto nl = static_cast<std::int64_t>(starts.size());
#pragma omp parallel for schedule(dynamic, 1024)
  for (std::int64_t l = 0; l < nl; ++l) {
    OctreeLeaf& leaf = tree.leaves_[l];
    leaf.first = starts[l];
    leaf.count = (l + 1 < nl ? starts[l + 1] : static_cast<std::uint32_t>(T.size())) - leaf.first;
    leaf.key = key_at(leaf.first);
    double A = 0.0;
    Eigen::Vector3d S = Eigen::Vector3d::Zero(), P = Eigen::Vector3d::Zero();
    for (std::uint32_t k = leaf.first; k < leaf.first + leaf.count; ++k) {
      const TriangleSums& ts = sums[tree.order_[k]];
      const Eigen::Vector3d half_cross = ts.half_cross.cast<double>();
      const double area = half_cross.norm();
      A += area;
      S += half_cross;
      P += area * ts.centroid.cast<double>();
    }
    leaf.area = A;
    leaf.sum_an = S;
    leaf.sum_ac = P;
  }
  tree.prefix_area_.resize(starts.size() + 1);
  tree.prefix_an_.resize(starts.size() + 1);
  tree.prefix_area_[0] = 0.0;
  tree.prefix_an_[0].setZero();
  for (std::size_t l = 0; l < starts.size(); ++l) {
    tree.prefix_area_[l + 1] = tree.prefix_area_[l] + tree.leaves_[l].area;
    tree.prefix_an_[l + 1] = tree.prefix_an_[l] + tree.leaves_[l].sum_an;
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
  return leaves_.capacity() * sizeof(OctreeLeaf) + order_.capacity() * 4 + prefix_area_.capacity() * 8 +
         prefix_an_.capacity() * sizeof(Eigen::Vector3d);
}

}  // namespace dentmark::detect
