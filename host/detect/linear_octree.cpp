#include "dentmark/host/detect/linear_octree.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "leaf_sums.h"
#include "threads.h"

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

  // Bounding box of the vertices (finite by ingest's contract), unless the reader
  // measured it on its way.
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max()), hi = -lo;
  if (mesh.has_bounds()) {
    lo = mesh.bounds_min(), hi = mesh.bounds_max();
  } else {
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
  }
  const double extent = (hi - lo).cast<double>().maxCoeff() + leaf_size;
  int depth = 1;
  while (leaf_size * std::ldexp(1.0, depth) < extent) ++depth;
  // 16 levels: 65 536 finest nodes a side (65 m at 1 mm); a bucket's cell fits 32 bits.
  if (depth > kMaxDepth)
    throw std::invalid_argument("finest node too small for the scan's extent (more than 65536 nodes a side)");
  LinearOctree tree;
  tree.depth_ = depth;
  tree.leaf_size_ = leaf_size;
  tree.origin_ = lo.cast<double>() - Eigen::Vector3d::Constant(0.5 * leaf_size);
  detail::LeafBuildStats stats;
  tree.leaves_ = detail::accumulate_leaves(
      mesh, {tree.origin_.cast<float>(), static_cast<float>(1.0 / leaf_size), depth}, &stats);
  tree.build_bytes_ = stats.record_bytes;

  return tree;
}

LinearOctree LinearOctree::subset(const std::vector<std::uint8_t>& keep) const {
  if (keep.size() != leaves_.size()) throw std::invalid_argument("octree subset: one flag per leaf");
  LinearOctree tree;
  tree.origin_ = origin_, tree.leaf_size_ = leaf_size_, tree.depth_ = depth_;
  const auto kept = static_cast<std::size_t>(
      std::count_if(keep.begin(), keep.end(), [](std::uint8_t k) { return k != 0; }));
  tree.leaves_ = OctreeLeaves(kept);
  OctreeLeaf* out = tree.leaves_.block();
  for (std::size_t l = 0; l < leaves_.size(); ++l)
    if (keep[l]) *out++ = leaves_[l];
  tree.leaves_.set_window(0, kept);
  return tree;
}

namespace {

// Eq. (2)-(3) from a node's sums.
NodeStats from_sums(double area, const Eigen::Vector3d& sum_an) {
  NodeStats s;
  s.area = area;
  if (!(area > 0.0)) return s;
  s.mean_normal = sum_an / area;                                          // eq. (2)
  s.sigma = std::sqrt(std::max(0.0, 1.0 - s.mean_normal.squaredNorm()));  // eq. (3)
  return s;
}

}  // namespace

NodeStats LinearOctree::stats(std::size_t begin, std::size_t end) const {
  double area = 0.0;
  Eigen::Vector3d sum_an = Eigen::Vector3d::Zero();
  for (std::size_t l = begin; l < end; ++l)
    area += leaves_[l].area, sum_an += leaves_[l].sum_an.cast<double>();
  return from_sums(area, sum_an);
}

namespace {

// A node of the octree: its leaves [begin, end) and its level (0: the root).
struct Node {
  std::size_t begin, end;
  int level;
};

// The sums of each node at level `top`, and the first leaf at or after each (the node's
// leaves are [first[n], first[n + 1])).
struct TopLevel {
  int top = 0;
  std::vector<double> area;
  std::vector<Eigen::Vector3d> sum_an;
  std::vector<std::size_t> first;
};

// One pass over the leaves. A node's leaves are one run: each thread sums whole nodes,
// in leaf order (the same sums whatever the thread count). Part p starts at the first
// node beginning in it.
TopLevel top_level_sums(const OctreeLeaves& leaves, int depth, int top) {
  TopLevel t;
  t.top = top;
  const int top_shift = 3 * (depth - top);
  const std::size_t top_nodes = std::size_t{1} << (3 * top);
  t.area.assign(top_nodes, 0.0);
  t.sum_an.assign(top_nodes, Eigen::Vector3d::Zero());
  t.first.assign(top_nodes + 1, leaves.size());
  const auto top_node = [&](std::size_t l) { return static_cast<std::size_t>(leaves[l].key >> top_shift); };
  const auto parts = static_cast<std::int64_t>(detail::thread_count());
  const auto part_begin = [&](std::int64_t p) {
    std::size_t l = leaves.size() * static_cast<std::size_t>(p) / static_cast<std::size_t>(parts);
    while (l > 0 && l < leaves.size() && top_node(l) == top_node(l - 1)) ++l;
    return l;
  };
#pragma omp parallel for schedule(static, 1)
  for (std::int64_t p = 0; p < parts; ++p)
    for (std::size_t l = part_begin(p), e = part_begin(p + 1); l < e; ++l) {
      const std::size_t n = top_node(l);
      t.area[n] += leaves[l].area;
      t.sum_an[n] += leaves[l].sum_an.cast<double>();
      t.first[n] = std::min(t.first[n], l);
    }
  for (std::size_t n = top_nodes; n-- > 0;) t.first[n] = std::min(t.first[n], t.first[n + 1]);
  return t;
}

// Level by level from the root down to `top`, each node's sums from its descendants at
// level `top`: the level-`top` nodes whose normals still vary over split_sigma.
std::vector<Node> split_to_top(const TopLevel& t, double split_sigma) {
  std::vector<Node> frontier;
  std::vector<std::size_t> split{0};
  for (int level = 0; level < t.top; ++level) {
    const int below = 3 * (t.top - level - 1);  // a child's span of level-`top` nodes, in bits
    std::vector<std::size_t> next;
    for (const std::size_t node : split)
      for (std::size_t c = 8 * node; c < 8 * node + 8; ++c) {
        const std::size_t lo = c << below, hi = (c + 1) << below;
        if (t.first[lo] == t.first[hi]) continue;  // no leaves
        double a = 0.0;
        Eigen::Vector3d s = Eigen::Vector3d::Zero();
        for (std::size_t n = lo; n < hi; ++n) a += t.area[n], s += t.sum_an[n];
        if (from_sums(a, s).sigma <= split_sigma) continue;
        if (level + 1 < t.top)
          next.push_back(c);
        else
          frontier.push_back({t.first[lo], t.first[hi], t.top});
      }
    split = std::move(next);
  }
  return frontier;
}

// Splits a node's subtree down to the leaves: one scan of a node's range gives its eight
// children's ranges and sums. Appends the first leaf index of each feature leaf to out.
void split_subtree(const OctreeLeaves& leaves, int depth, const Node& root, double split_sigma,
                   double leaf_sigma, std::vector<Node>& stack, std::vector<std::uint32_t>& out) {
  stack.push_back(root);
  while (!stack.empty()) {
    const Node node = stack.back();
    stack.pop_back();
    const int shift = 3 * (depth - node.level - 1);
    std::size_t bounds[9];
    double area[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    Eigen::Vector3d sum_an[8];
    for (auto& a : sum_an) a.setZero();
    bounds[0] = node.begin;
    int child = 0;
    for (std::size_t l = node.begin; l < node.end; ++l) {
      const auto c = static_cast<int>((leaves[l].key >> shift) & 7);
      while (child < c) bounds[++child] = l;
      area[c] += leaves[l].area;
      sum_an[c] += leaves[l].sum_an.cast<double>();
    }
    while (child < 8) bounds[++child] = node.end;
    for (int c = 7; c >= 0; --c) {
      if (bounds[c] == bounds[c + 1]) continue;
      const double sigma = from_sums(area[c], sum_an[c]).sigma;
      if (node.level + 1 == depth) {
        // A leaf: one cell, one range of triangles.
        if (sigma > leaf_sigma) out.push_back(static_cast<std::uint32_t>(bounds[c]));
      } else if (sigma > split_sigma) {
        stack.push_back({bounds[c], bounds[c + 1], node.level + 1});
      }
    }
  }
}

}  // namespace

std::vector<std::uint32_t> LinearOctree::feature_leaves(double split_sigma, double leaf_sigma) const {
  // Top-down (eq. 3). A node's leaves are one range. The coarse levels, which every
  // panel's curvature splits, come from one pass of sums per node at level `top` (each
  // level would otherwise scan every leaf again); below it, one scan of a node's range
  // gives its eight children's ranges and sums, so each level costs one pass over the
  // leaves still being split (no prefix arrays: 33 MB of fresh memory on a 9 M-triangle
  // scan).
  const int top = std::min(depth_ - 1, 5);  // 8^5 nodes: 1 MB of sums
  std::vector<Node> frontier = split_to_top(top_level_sums(leaves_, depth_, top), split_sigma);
  if (top == 0) frontier.push_back({0, leaves_.size(), 0});

  // Below `top` each frontier node's subtree is split on its own (by whichever thread is
  // free); the leaves found are sorted at the end, so the order of work does not matter.
  const auto parts = static_cast<std::size_t>(detail::thread_count());
  std::vector<std::vector<std::uint32_t>> found(parts);
  const int team = static_cast<int>(parts);  // at most one list per thread
#pragma omp parallel num_threads(team)
  {
    std::vector<std::uint32_t>& out = found[static_cast<std::size_t>(detail::thread_index())];
    std::vector<Node> stack;
#pragma omp for schedule(dynamic, 4)
    for (std::size_t f = 0; f < frontier.size(); ++f)
      split_subtree(leaves_, depth_, frontier[f], split_sigma, leaf_sigma, stack, out);
  }
  std::vector<std::uint32_t> out;
  for (const auto& f : found) out.insert(out.end(), f.begin(), f.end());
  std::sort(out.begin(), out.end());
  return out;
}

std::size_t LinearOctree::bytes() const {
  return leaves_.size() * sizeof(OctreeLeaf) + build_bytes_;  // capacity beyond: never touched
}

}  // namespace dentmark::detect
