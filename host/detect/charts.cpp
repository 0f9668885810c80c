#include "charts.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "dentmark/common/nth_smallest.h"
#include "threads.h"

namespace dentmark::detect {
namespace {

// Coarse nodes at least this wide: a dent (≤ 30 mm) or a handle's side does not turn
// their normal, the panel's curvature does.
constexpr double kNodeSize = 0.016;
// A scan needs charts when more than kSteepShare of its surface turns more than kSteep
// from the mean normal. Past 60 degrees a map pixel holds a strip of surface twice its
// width; at 55 degrees on a 0.2 m radius the reference's quadratic already left 30-140 um
// dents and bumps that were not there (the other generator's tight fenders).
constexpr double kSteep = 45.0 * std::numbers::pi / 180.0;
constexpr double kSteepShare = 0.03;
// Charts are added until all but kUncoveredShare of the surface lies within kCover of an
// axis; a chart's map takes the surface within kReach of its axis (the margin round it).
// At 45 degrees of cover (fewer charts) a quadratic reference could not follow a 0.15 m
// tube's steep sides near its edge; beyond 55 degrees of reach, neither near the chart's.
constexpr double kCover = 30.0 * std::numbers::pi / 180.0;
constexpr double kUncoveredShare = 0.005;
constexpr double kReach = 55.0 * std::numbers::pi / 180.0;
constexpr int kMaxCharts = 6;
constexpr double kMinChartShare = 0.01;  // of the surface, for a chart of its own
// A node whose normals cancel out (|S| / A below this: outliers, a crumpled corner) has
// no direction of its own; it takes its neighbour's along the key order.
constexpr double kCoherent = 0.3;
// A node of smooth panel: the spread of its normals (eq. 3's σ) at most that of the scan's
// noise and kSmoothSpread more (sigma² adds up): 15 degrees.
constexpr double kSmoothSpread = 0.26;

struct Node {
  std::uint64_t key;
  double area;
  Eigen::Vector3d normal;  // unit
  double coherence = 0.0;  // |S| / A: 1 on a smooth panel, less across a handle's edge
};

int nearest_axis(const std::vector<Eigen::Vector3d>& axes, const Eigen::Vector3d& n, double* dot = nullptr) {
  int best = 0;
  double best_dot = -2.0;
  for (std::size_t c = 0; c < axes.size(); ++c)
    if (const double d = axes[c].dot(n); d > best_dot) best_dot = d, best = static_cast<int>(c);
  if (dot) *dot = best_dot;
  return best;
}

// Coarse nodes of the tree, in key order, with coherent normals.
std::vector<Node> coarse_nodes(const LinearOctree& tree, int shift) {
  const auto& leaves = tree.leaves();
  const auto node_of = [&](std::size_t l) { return leaves[l].key >> shift; };
  // The leaves in one run of whole nodes per thread: a node's sums in leaf order, as one
  // thread would sum them.
  const auto parts = static_cast<std::size_t>(detail::thread_count());
  std::vector<std::size_t> cut(parts + 1, leaves.size());
  cut[0] = 0;
  for (std::size_t p = 1; p < parts; ++p) {
    std::size_t l = std::max(cut[p - 1], leaves.size() * p / parts);
    while (l > 0 && l < leaves.size() && node_of(l) == node_of(l - 1)) ++l;
    cut[p] = l;
  }
  std::vector<std::vector<Node>> part_nodes(parts);
  std::vector<std::vector<Eigen::Vector3d>> part_sums(parts);
  detail::for_each_part(parts, [&](std::size_t p) {
    std::vector<Node>& nodes = part_nodes[p];
    std::vector<Eigen::Vector3d>& sums = part_sums[p];
    for (std::size_t i = cut[p]; i < cut[p + 1]; ++i) {
      const OctreeLeaf& l = leaves[i];
      const std::uint64_t k = node_of(i);
      if (nodes.empty() || nodes.back().key != k)
        nodes.push_back({k, 0.0, Eigen::Vector3d::Zero()}), sums.emplace_back(0, 0, 0);
      nodes.back().area += l.area;
      sums.back() += l.sum_an.cast<double>();
    }
  });
  std::vector<Node> nodes;
  std::vector<Eigen::Vector3d> sums;
  for (std::size_t p = 0; p < parts; ++p) {
    nodes.insert(nodes.end(), part_nodes[p].begin(), part_nodes[p].end());
    sums.insert(sums.end(), part_sums[p].begin(), part_sums[p].end());
  }
  // Incoherent nodes take the previous coherent node's normal (the next one's at the start).
  std::size_t first_coherent = nodes.size();
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    const double s = sums[i].norm();
    nodes[i].coherence = nodes[i].area > 0.0 ? s / nodes[i].area : 0.0;
    if (nodes[i].area > 0.0 && s >= kCoherent * nodes[i].area) {
      nodes[i].normal = sums[i] / s;
      first_coherent = std::min(first_coherent, i);
    }
  }
  if (first_coherent == nodes.size()) return {};
  Eigen::Vector3d last = nodes[first_coherent].normal;
  for (Node& n : nodes) {
    if (n.normal.squaredNorm() > 0.0)
      last = n.normal;
    else
      n.normal = last;
  }
  return nodes;
}

}  // namespace

Charts find_charts(const LinearOctree& tree, double noise_sigma) {
  Charts charts;
  const double smooth =
      std::sqrt(std::max(0.0, 1.0 - noise_sigma * noise_sigma - kSmoothSpread * kSmoothSpread));
  int levels = 0;
  while (levels < tree.depth() && std::ldexp(tree.leaf_size(), levels) < kNodeSize) ++levels;
  charts.node_shift = 3 * levels;
  const std::vector<Node> nodes = coarse_nodes(tree, charts.node_shift);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  double total = 0.0;
  for (const Node& n : nodes) mean += n.area * n.normal, total += n.area;
  if (nodes.empty() || !(mean.norm() > 0.0)) return charts;
  charts.axes = {mean.normalized()};

  // Steep panel, not a handle's or a flange's wall: that takes a node whose normals agree
  // (a 16 mm node across the edge of a handle standing 18 mm proud does not).
  double steep = 0.0;
  for (const Node& n : nodes)
    if (n.coherence >= smooth && n.normal.dot(charts.axes[0]) < std::cos(kSteep)) steep += n.area;
  if (steep <= kSteepShare * total) return charts;

  // Spherical k-means (area-weighted), seeded farthest-first: each new axis at the
  // node turned furthest from its nearest axis, among nodes of a typical size (a stray
  // point's node must not seed a chart).
  std::vector<double> areas;
  for (const Node& n : nodes) areas.push_back(n.area);
  const double typical = 0.5 * median_in_place(areas);
  std::vector<int> assigned(nodes.size(), 0);
  while (true) {
    for (int iteration = 0; iteration < 20; ++iteration) {
      std::vector<Eigen::Vector3d> sum(charts.axes.size(), Eigen::Vector3d::Zero());
      bool moved = false;
      for (std::size_t i = 0; i < nodes.size(); ++i) {
        const int c = nearest_axis(charts.axes, nodes[i].normal);
        moved |= c != assigned[i];
        assigned[i] = c;
        sum[static_cast<std::size_t>(c)] += nodes[i].area * nodes[i].normal;
      }
      for (std::size_t c = 0; c < sum.size(); ++c)
        if (sum[c].norm() > 0.0) charts.axes[c] = sum[c].normalized();
      if (!moved && iteration > 0) break;
    }
    double uncovered = 0.0, worst = 2.0;
    std::size_t seed = 0;
    for (std::size_t i = 0; i < nodes.size(); ++i) {
      double dot = 0.0;
      nearest_axis(charts.axes, nodes[i].normal, &dot);
      if (dot < std::cos(kCover)) uncovered += nodes[i].area;
      if (nodes[i].area >= typical && nodes[i].coherence >= smooth && dot < worst) worst = dot, seed = i;
    }
    if (uncovered <= kUncoveredShare * total || static_cast<int>(charts.axes.size()) == kMaxCharts ||
        worst > 1.0)  // (no smooth node of a typical size left to seed a chart)
      break;
    charts.axes.push_back(nodes[seed].normal);
  }
  // A chart of next to nothing (a stray point's cluster, a sliver between two axes) is no
  // map: its nodes go to the nearest other axis.
  {
    std::vector<double> owned(charts.axes.size(), 0.0);
    for (const Node& n : nodes)
      owned[static_cast<std::size_t>(nearest_axis(charts.axes, n.normal))] += n.area;
    std::vector<Eigen::Vector3d> kept;
    for (std::size_t c = 0; c < charts.axes.size(); ++c)
      if (owned[c] >= kMinChartShare * total) kept.push_back(charts.axes[c]);
    if (kept.empty()) kept.push_back(charts.axes[0]);
    charts.axes = std::move(kept);
  }
  if (charts.axes.size() == 1) {
    charts.axes = {mean.normalized()};
    return charts;
  }

  charts.node_keys.reserve(nodes.size());
  charts.node_chart.reserve(nodes.size());
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    charts.node_keys.push_back(nodes[i].key);
    charts.node_chart.push_back(static_cast<std::uint8_t>(nearest_axis(charts.axes, nodes[i].normal)));
  }
  charts.node_normals.reserve(nodes.size());
  for (const Node& n : nodes) charts.node_normals.push_back(n.normal.cast<float>());
  return charts;
}

int Charts::owner(const LinearOctree& tree, const Eigen::Vector3d& p) const {
  if (node_keys.empty()) return axes.empty() ? -1 : 0;
  Eigen::Vector3i cell;
  const int cells = 1 << tree.depth();
  for (int a = 0; a < 3; ++a)
    cell[a] = static_cast<int>(std::clamp(std::floor((p[a] - tree.origin()[a]) / tree.leaf_size()), 0.0,
                                          static_cast<double>(cells - 1)));
  const std::uint64_t key = LinearOctree::encode(cell) >> node_shift;
  auto it = std::lower_bound(node_keys.begin(), node_keys.end(), key);
  if (it == node_keys.end()) --it;
  return node_chart[static_cast<std::size_t>(it - node_keys.begin())];
}

std::vector<std::uint8_t> Charts::members(const LinearOctree& tree, int c) const {
  const auto& leaves = tree.leaves();
  std::vector<std::uint8_t> in(leaves.size(), 0);
  const Eigen::Vector3f axis = axes[static_cast<std::size_t>(c)].cast<float>();
  const auto reach = static_cast<float>(std::cos(kReach));
  std::size_t node = 0;
  for (std::size_t l = 0; l < leaves.size(); ++l) {
    const std::uint64_t k = leaves[l].key >> node_shift;
    while (node_keys[node] != k) ++node;
    in[l] = node_chart[node] == c || node_normals[node].dot(axis) >= reach;
  }
  return in;
}

}  // namespace dentmark::detect
