// Linear octree: eq. (1)-(3) from sums match the brute-force definitions; subdivision
// finds what is sharp; grouping (eq. 4, 26-adjacency) splits and drops correctly; subsets
// and the charts of a surface that wraps round.
#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <random>

#include "../../host/detect/charts.h"
#include "../../host/detect/leaf_sums.h"
#include "dentmark/host/detect/grouping.h"
#include "dentmark/host/detect/height_map.h"
#include "dentmark/host/detect/linear_octree.h"

namespace dentmark::detect {
namespace {

// A height field z(x, y) on an n x n grid of the given step, as a mesh.
template <typename F>
ingest::Mesh grid_mesh(int n, double step, F&& z) {
  ingest::Mesh m;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) m.vertices.emplace_back(x * step, y * step, z(x * step, y * step));
  for (int y = 0; y + 1 < n; ++y)
    for (int x = 0; x + 1 < n; ++x) {
      const auto a = static_cast<std::uint32_t>(y * n + x), b = a + 1, c = a + static_cast<std::uint32_t>(n),
                 d = c + 1;
      m.triangles.push_back({a, b, d});
      m.triangles.push_back({a, d, c});
    }
  return m;
}

TEST(LinearOctree, MortonRoundTrip) {
  std::mt19937 rng(1);
  for (int i = 0; i < 1000; ++i) {
    const Eigen::Vector3i c(static_cast<int>(rng() % (1 << 21)), static_cast<int>(rng() % (1 << 21)),
                            static_cast<int>(rng() % (1 << 21)));
    EXPECT_EQ(LinearOctree::decode(LinearOctree::encode(c)), c);
  }
  // Morton order: a parent's 8 children are consecutive.
  EXPECT_EQ(LinearOctree::encode({1, 1, 1}), 7u);
  EXPECT_EQ(LinearOctree::encode({2, 0, 0}), 8u);
}

TEST(LinearOctree, SigmaFromSumsEqualsEquation3) {
  std::mt19937 rng(7);
  std::normal_distribution<double> g(0.0, 0.002);
  const ingest::Mesh m =
      grid_mesh(40, 0.001, [&](double x, double y) { return 0.05 * x * x + 0.2 * y + g(rng); });
  const LinearOctree tree = LinearOctree::build(m, 0.004);
  // Brute force eq. (1)-(3) for whole tree and for random leaf ranges.
  std::uniform_int_distribution<std::size_t> pick(0, tree.leaves().size());
  for (int trial = 0; trial < 20; ++trial) {
    std::size_t b = pick(rng), e = pick(rng);
    if (trial == 0) b = 0, e = tree.leaves().size();
    if (b > e) std::swap(b, e);
    if (b == e) continue;
    std::vector<double> a;
    std::vector<Eigen::Vector3d> N;
    // Triangles of leaves [b, e): their keys lie in [key(b), key(e - 1)].
    const std::uint64_t k0 = tree.leaves()[b].key, k1 = tree.leaves()[e - 1].key;
    std::size_t in_range = 0;
    for (std::size_t i = 0; i < m.triangles.size(); ++i) {
      const std::uint64_t key = tree.triangle_key(m, i);
      if (key < k0 || key > k1) continue;
      ++in_range;
      const auto& t = m.triangles[i];
      const Eigen::Vector3d v1 = (m.vertices[t[1]] - m.vertices[t[0]]).cast<double>(),
                            v2 = (m.vertices[t[2]] - m.vertices[t[0]]).cast<double>();
      a.push_back(0.5 * v1.cross(v2).norm());  // eq. (1)
      N.push_back(v1.cross(v2).normalized());
    }
    std::size_t counted = 0;
    for (std::size_t l = b; l < e; ++l) counted += tree.leaves()[l].count;
    EXPECT_EQ(counted, in_range);
    double A = 0;
    Eigen::Vector3d Nbar = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < a.size(); ++i) A += a[i], Nbar += a[i] * N[i];
    Nbar /= A;  // eq. (2)
    double var = 0;
    for (std::size_t i = 0; i < a.size(); ++i) var += a[i] * (N[i] - Nbar).squaredNorm();
    const double sigma = std::sqrt(var / A);  // eq. (3)
    const NodeStats s = tree.stats(b, e);
    EXPECT_NEAR(s.area, A, 1e-6 * A);  // float vertices
    EXPECT_NEAR(s.sigma, sigma, 1e-5);
    EXPECT_GT(sigma, 0.01);  // the test has teeth: the noise spreads the normals
  }
}

TEST(LinearOctree, LeavesDoNotDependOnTriangleOrder) {
  ingest::Mesh m = grid_mesh(50, 0.001, [](double x, double y) { return 0.1 * std::sin(40 * x) * y; });
  const LinearOctree a = LinearOctree::build(m, 0.002);
  std::mt19937 rng(5);
  std::shuffle(m.triangles.begin(), m.triangles.end(), rng);
  const LinearOctree b = LinearOctree::build(m, 0.002);
  ASSERT_EQ(a.leaves().size(), b.leaves().size());
  for (std::size_t i = 0; i < a.leaves().size(); ++i) {
    EXPECT_EQ(a.leaves()[i].key, b.leaves()[i].key);
    EXPECT_NEAR(a.leaves()[i].area, b.leaves()[i].area, 1e-12);
    EXPECT_EQ(a.leaves()[i].count, b.leaves()[i].count);
  }
  EXPECT_EQ(a.depth(), b.depth());
  EXPECT_NEAR(a.leaf_size(), 0.002, 1e-15);
}

// How close a leaf's sums are to the truth, relative to its area and in metres.
struct Precision {
  double relative;
  double centroid;
};
// Sensor order: open leaves sum floats and keep the mean point in 1/65536 of a leaf (15 nm
// at 1 mm; float centroids at 0.2 m: ~45 nm).
constexpr Precision kOpenLeaves{1e-5, 1e-7};
// Random order: a triangle filed on its own keeps a_i N_i to 2^-12 of its area (block
// floating point) and its centroid to 1/1024 of a leaf (depth <= 13); 1 mm leaves here.
constexpr Precision kSingles{5e-4, 1e-6};

// Every leaf's count, A, S and mean point against sums per cell done the slow way.
void expect_leaf_sums_match_brute_force(const ingest::Mesh& m, double leaf_size, Precision precision) {
  const LinearOctree tree = LinearOctree::build(m, leaf_size);
  struct Sums {
    std::uint32_t count = 0;
    double area = 0;
    Eigen::Vector3d an = Eigen::Vector3d::Zero(), ac = Eigen::Vector3d::Zero();
  };
  std::map<std::uint64_t, Sums> truth;
  for (std::size_t i = 0; i < m.triangles.size(); ++i) {
    const auto& t = m.triangles[i];
    const Eigen::Vector3d a = m.vertices[t[0]].cast<double>(), b = m.vertices[t[1]].cast<double>(),
                          c = m.vertices[t[2]].cast<double>();
    const Eigen::Vector3d an = 0.5 * (b - a).cross(c - a);
    Sums& s = truth[tree.triangle_key(m, i)];
    s.count += 1;
    s.area += an.norm();
    s.an += an;
    s.ac += an.norm() * (a + b + c) / 3.0;
  }
  ASSERT_EQ(tree.leaves().size(), truth.size());
  auto it = truth.begin();
  for (const OctreeLeaf& leaf : tree.leaves()) {
    ASSERT_EQ(leaf.key, it->first);  // Morton order
    EXPECT_EQ(leaf.count, it->second.count);
    EXPECT_NEAR(leaf.area, it->second.area, precision.relative * it->second.area);
    EXPECT_LT((leaf.sum_an.cast<double>() - it->second.an).norm(), precision.relative * it->second.area);
    if (it->second.area > 0) {
      EXPECT_LT((leaf.centroid.cast<double>() - it->second.ac / it->second.area).norm(), precision.centroid);
    }
    ++it;
  }
}

TEST(LinearOctree, LeafSumsEqualBruteForcePerCell) {
  // Many sort buckets and many triangles per leaf; in sensor order and shuffled.
  std::mt19937 rng(11);
  std::normal_distribution<double> g(0.0, 0.0002);
  ingest::Mesh m = grid_mesh(400, 0.0005, [&](double x, double y) { return 0.3 * x * y + g(rng); });
  expect_leaf_sums_match_brute_force(m, 0.001, kOpenLeaves);
  std::shuffle(m.triangles.begin(), m.triangles.end(), rng);
  expect_leaf_sums_match_brute_force(m, 0.001, kSingles);
}

TEST(LinearOctree, LeafSumsAreRightWhenTheOrderChangesWithinAScan) {
  // Sensor order, then a shuffled stretch, then sensor order again: pass 1 switches
  // between open leaves and one record per triangle, and back.
  ingest::Mesh m = grid_mesh(500, 0.0005, [](double x, double y) { return 0.2 * x * x - 0.1 * y; });
  std::mt19937 rng(3);
  const auto third = static_cast<std::ptrdiff_t>(m.triangles.size() / 3);
  std::shuffle(m.triangles.begin() + third, m.triangles.begin() + 2 * third, rng);
  expect_leaf_sums_match_brute_force(m, 0.001, kSingles);
}

TEST(LinearOctree, LeafSumsAreRightInTheDeepestTree) {
  // Depth 16 (4 um leaves over 0.15 m): a bucket is 2^10 leaves a side, and a triangle
  // filed on its own keeps its position in the leaf in the 6 bits left.
  std::mt19937 rng(13);
  ingest::Mesh m = grid_mesh(300, 0.0005, [](double x, double y) { return 0.2 * x * y; });
  std::shuffle(m.triangles.begin(), m.triangles.end(), rng);
  ASSERT_EQ(LinearOctree::build(m, 4e-6).depth(), 16);
  expect_leaf_sums_match_brute_force(m, 4e-6, kSingles);
}

TEST(LinearOctree, LeafSumsAreTheSameWhateverTheThreadCount) {
  // Pass 2 writes the leaves of thread pairs from their meeting point outwards, and moves
  // the pairs' runs together: 1 to 5 threads (odd counts leave a thread without a pair).
  std::mt19937 rng(8);
  std::normal_distribution<double> g(0.0, 0.0001);
  ingest::Mesh m = grid_mesh(300, 0.0005, [&](double x, double y) { return 0.1 * x * x + g(rng) - 0.2 * y; });
  const int initial = omp_get_max_threads();
  for (int threads = 1; threads <= 5; ++threads) {
    SCOPED_TRACE(threads);
    omp_set_num_threads(threads);
    expect_leaf_sums_match_brute_force(m, 0.001, kOpenLeaves);
  }
  omp_set_num_threads(initial);
}

// An n x n grid of a noisy saddle in sensor order, with its middle third of triangles
// shuffled: open leaves and single records both.
ingest::Mesh sensor_order_with_a_shuffled_stretch(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 0.0001);
  ingest::Mesh m = grid_mesh(n, 0.0005, [&](double x, double y) { return 0.1 * x * y + g(rng); });
  const auto third = static_cast<std::ptrdiff_t>(m.triangles.size() / 3);
  std::shuffle(m.triangles.begin() + third, m.triangles.begin() + 2 * third, rng);
  return m;
}

// How many leaves differ in any bit of any field (the counts must match first).
std::size_t differing_leaves(const OctreeLeaves& x, const OctreeLeaves& y) {
  std::size_t differing = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    const OctreeLeaf &a = x[i], &b = y[i];
    differing += a.key != b.key || a.count != b.count || a.area != b.area || a.sum_an != b.sum_an ||
                 a.centroid != b.centroid;
  }
  return differing;
}

TEST(LinearOctree, LeavesAreBitIdenticalWhateverThreadTookWhichSlice) {
  // Threads take slices of the triangles as they come free, so which thread files which
  // slice changes from run to run; the float sums must not. 11 slices, 1 to 5 threads,
  // repeated runs.
  const ingest::Mesh m = sensor_order_with_a_shuffled_stretch(600, 21);
  const int initial = omp_get_max_threads();
  omp_set_num_threads(1);
  const LinearOctree reference = LinearOctree::build(m, 0.001);
  for (int threads : {2, 2, 2, 3, 4, 5}) {
    SCOPED_TRACE(threads);
    omp_set_num_threads(threads);
    const LinearOctree tree = LinearOctree::build(m, 0.001);
    ASSERT_EQ(tree.leaves().size(), reference.leaves().size());
    EXPECT_EQ(differing_leaves(tree.leaves(), reference.leaves()), 0u);
  }
  omp_set_num_threads(initial);
}

TEST(LinearOctree, LeavesAreBitIdenticalWhenAThreadTakesOverAnothersBuckets) {
  // In pass 2 a thread done with its own buckets takes over its partner's from the far
  // end, and the runs are moved together afterwards. Which buckets change hands depends on
  // the threads' speeds; the leaves must not. More threads than cores (2 to 5 on this
  // machine's cores or fewer) make it happen: repeated until it has, 3 times at least.
  const ingest::Mesh m = sensor_order_with_a_shuffled_stretch(500, 5);
  const ingest::MeshView view(m);
  const detail::LeafGrid grid{Eigen::Vector3f(-0.2f, -0.2f, -0.2f), 1000.0f, 9};  // 1 mm, 0.51 m a side
  const int initial = omp_get_max_threads();
  omp_set_num_threads(1);
  const OctreeLeaves reference = detail::accumulate_leaves(view, grid);
  std::size_t runs_taken_over = 0;
  for (int run = 0; run < 400 && runs_taken_over < 3; ++run) {
    const int threads = 2 + run % 4;
    SCOPED_TRACE(threads);
    omp_set_num_threads(threads);
    detail::LeafBuildStats stats;
    const OctreeLeaves leaves = detail::accumulate_leaves(view, grid, &stats);
    runs_taken_over += stats.buckets_taken_over > 0;
    ASSERT_EQ(leaves.size(), reference.size());
    ASSERT_EQ(differing_leaves(leaves, reference), 0u)
        << "run " << run << ", " << stats.buckets_taken_over << " buckets taken over";
  }
  omp_set_num_threads(initial);
  EXPECT_EQ(runs_taken_over, 3u);
}

TEST(LinearOctree, FarMoreLeavesThanTheSurfaceAreaSuggestsAreAllKept) {
  // Tiny slivers scattered through a 0.2 m cube: almost no area, one leaf and one record
  // each, spread over many buckets (no open leaf is ever hit, so after the first block
  // they are filed as single records: their precision).
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 0.2f), d(-1e-6f, 1e-6f);
  ingest::Mesh m = grid_mesh(20, 0.0005, [](double, double) { return 0.0; });
  for (int i = 0; i < 20000; ++i) {
    const Eigen::Vector3f p(u(rng), u(rng), u(rng));
    const auto base = static_cast<std::uint32_t>(m.vertices.size());
    m.vertices.push_back(p);
    m.vertices.push_back(p + Eigen::Vector3f(d(rng), d(rng), d(rng)));
    m.vertices.push_back(p + Eigen::Vector3f(d(rng), d(rng), d(rng)));
    m.triangles.push_back({base, base + 1, base + 2});
  }
  expect_leaf_sums_match_brute_force(m, 0.001, kSingles);
}

// The top-down subdivision the slow way: every node's σ from stats() over its range.
std::vector<std::uint32_t> feature_leaves_by_hand(const LinearOctree& t, double split_sigma,
                                                  double leaf_sigma) {
  std::vector<std::uint32_t> out;
  const auto& leaves = t.leaves();
  const std::function<void(std::size_t, std::size_t, int)> split = [&](std::size_t b, std::size_t e,
                                                                       int level) {
    const int shift = 3 * (t.depth() - level - 1);
    for (std::size_t i = b, j = b; i < e; i = j) {
      while (j < e && (leaves[j].key >> shift) == (leaves[i].key >> shift)) ++j;
      const double sigma = t.stats(i, j).sigma;
      if (level + 1 == t.depth()) {
        if (sigma > leaf_sigma) out.push_back(static_cast<std::uint32_t>(i));
      } else if (sigma > split_sigma) {
        split(i, j, level + 1);
      }
    }
  };
  split(0, leaves.size(), 0);
  return out;
}

TEST(LinearOctree, SubdivisionEqualsTheNodeByNodeDefinition) {
  // A curved, noisy panel with bumps and a ridge, 8 levels deep (the coarse levels come
  // from one pass of sums, the fine ones from range scans).
  std::mt19937 rng(21);
  std::normal_distribution<double> g(0.0, 0.00002);
  const ingest::Mesh m = grid_mesh(400, 0.0005, [&](double x, double y) {
    const double bump = 0.0008 * std::exp(-(std::pow(x - 0.05, 2) + std::pow(y - 0.12, 2)) / 2e-5);
    const double ridge = x > 0.14 ? 0.3 * (x - 0.14) : 0.0;
    return 0.8 * x * x + 0.4 * x * y + bump + ridge + g(rng);
  });
  const LinearOctree tree = LinearOctree::build(m, 0.001);
  ASSERT_GE(tree.depth(), 8);
  for (const auto& [split, leaf] : {std::pair{0.01, 0.03}, std::pair{0.03, 0.06}, std::pair{0.1, 0.2}}) {
    SCOPED_TRACE(split);
    const auto expected = feature_leaves_by_hand(tree, split, leaf);
    EXPECT_FALSE(expected.empty());
    EXPECT_EQ(tree.feature_leaves(split, leaf), expected);
  }
}

TEST(LinearOctree, SubdivisionFindsARidgeAndGroupingSeparatesTwo) {
  // Flat plane with two sharp ridges (fold of 0.6 rad) at x = 20 mm and x = 60 mm.
  auto z = [](double x, double) {
    return 0.3 * std::max(0.0, 0.004 - std::abs(x - 0.020)) +
           0.3 * std::max(0.0, 0.004 - std::abs(x - 0.060));
  };
  const ingest::Mesh m = grid_mesh(81, 0.001, z);
  const LinearOctree tree = LinearOctree::build(m, 0.002);
  const auto feat = tree.feature_leaves(0.1, 0.2);
  ASSERT_FALSE(feat.empty());
  for (auto l : feat) {
    const Eigen::Vector3d c = tree.leaves()[l].centroid.cast<double>();
    EXPECT_LT(std::min(std::abs(c.x() - 0.020), std::abs(c.x() - 0.060)), 0.0065) << c.transpose();
  }
  const auto groups = group_features(tree, feat, 0.0);
  EXPECT_EQ(groups.size(), 2u);
  // A very high occupancy floor removes everything (eq. 4 drops sparse nodes).
  EXPECT_TRUE(group_features(tree, feat, 100.0).empty());
}

TEST(LinearOctree, SubsetKeepsTheChosenLeavesAsTheyWere) {
  const ingest::Mesh m = grid_mesh(120, 0.0005, [](double x, double y) { return 0.2 * x * y; });
  const LinearOctree tree = LinearOctree::build(m, 0.001);
  std::vector<std::uint8_t> keep(tree.leaves().size());
  for (std::size_t l = 0; l < keep.size(); ++l) keep[l] = l % 3 == 1;
  const LinearOctree sub = tree.subset(keep);
  EXPECT_EQ(sub.depth(), tree.depth());
  EXPECT_EQ(sub.leaf_size(), tree.leaf_size());
  EXPECT_EQ(sub.origin(), tree.origin());
  ASSERT_EQ(sub.leaves().size(), (keep.size() + 1) / 3);
  for (std::size_t i = 0; i < sub.leaves().size(); ++i) {
    const OctreeLeaf &a = sub.leaves()[i], &b = tree.leaves()[3 * i + 1];
    EXPECT_EQ(a.key, b.key);
    EXPECT_EQ(a.count, b.count);
    EXPECT_EQ(a.area, b.area);
    EXPECT_EQ(a.sum_an, b.sum_an);
    EXPECT_EQ(a.centroid, b.centroid);
  }
  EXPECT_THROW(tree.subset(std::vector<std::uint8_t>(3, 1)), std::invalid_argument);
}

// A cylinder of radius R round the y axis, wrapped over +-half_angle, 0.2 m long, as a
// grid of the given step along the arc; its normals point outwards.
ingest::Mesh cylinder_mesh(double R, double half_angle, double step) {
  ingest::Mesh m;
  const int ns = static_cast<int>(2.0 * half_angle * R / step) + 1, nt = static_cast<int>(0.2 / step) + 1;
  for (int j = 0; j < nt; ++j)
    for (int i = 0; i < ns; ++i) {
      const double a = -half_angle + i * step / R;
      m.vertices.emplace_back(R * std::sin(a), j * step, R * std::cos(a));
    }
  for (int j = 0; j + 1 < nt; ++j)
    for (int i = 0; i + 1 < ns; ++i) {
      const auto a = static_cast<std::uint32_t>(j * ns + i), b = a + 1,
                 c = a + static_cast<std::uint32_t>(ns), d = c + 1;
      m.triangles.push_back({a, d, b});
      m.triangles.push_back({a, c, d});
    }
  return m;
}

TEST(Charts, ADoorLikePanelIsOneMap) {
  // Curved both ways (40 mm of sag over 0.4 m), and a handle: a box 100 x 18 mm standing
  // 18 mm proud, its sides upright. Neither turns 3 % of the surface past 60 degrees.
  ingest::Mesh m = grid_mesh(800, 0.0005, [](double x, double y) {
    const bool handle = std::abs(x - 0.2) < 0.05 && std::abs(y - 0.2) < 0.009;
    return 0.25 * (x - 0.2) * (x - 0.2) + 0.1 * (y - 0.2) * (y - 0.2) + (handle ? 0.018 : 0.0);
  });
  const Charts charts = find_charts(LinearOctree::build(m, 0.001), 0.0);
  ASSERT_EQ(charts.axes.size(), 1u);
}

TEST(Charts, AHalfCylinderIsCoveredByChartsWithinThirtyDegrees) {
  for (const double half_angle : {1.2, 1.5, 2.0}) {  // 69, 86 and 115 degrees round
    SCOPED_TRACE(half_angle);
    const LinearOctree tree = LinearOctree::build(cylinder_mesh(0.25, half_angle, 0.0008), 0.002);
    const Charts charts = find_charts(tree, 0.0);
    ASSERT_GE(charts.axes.size(), 2u);
    std::vector<std::vector<std::uint8_t>> members;
    for (std::size_t c = 0; c < charts.axes.size(); ++c)
      members.push_back(charts.members(tree, static_cast<int>(c)));
    for (std::size_t l = 0; l < tree.leaves().size(); ++l) {
      const OctreeLeaf& leaf = tree.leaves()[l];
      const Eigen::Vector3d normal = leaf.sum_an.cast<double>().normalized();
      // Each leaf owned by the chart nearest its normal, within 30 degrees (+ the spread
      // of a 16 mm node round 0.25 m, 4 degrees, and a leaf's own) of its axis, and in
      // that chart's map.
      const int owner = charts.owner(tree, leaf.centroid.cast<double>());
      ASSERT_GE(owner, 0);
      const auto c = static_cast<std::size_t>(owner);
      EXPECT_GT(normal.dot(charts.axes[c]), std::cos(0.65)) << "leaf " << l;
      EXPECT_TRUE(members[c][l]) << "leaf " << l;
      // A chart's map holds nothing turned more than 55 degrees from its axis (+ spread).
      for (std::size_t k = 0; k < charts.axes.size(); ++k)
        if (members[k][l]) {
          EXPECT_GT(normal.dot(charts.axes[k]), std::cos(1.05)) << "leaf " << l;
        }
    }
  }
}

TEST(Charts, AChartsMapHasNoGapsAcrossItsSurface) {
  // A chart's map looks at the cylinder's side 40-45 degrees off the octree's axes, where
  // the leaves' centroids fall in steps: columns of pixels got none, and read as cuts
  // through the panel (a dent beside one was taken for a border feature).
  for (const double turn : {0.0, 0.3, 0.6}) {
    SCOPED_TRACE(turn);
    ingest::Mesh m = cylinder_mesh(0.25, 1.5, 0.0005);
    for (auto& v : m.vertices)  // turned round the cylinder's axis (y)
      v = Eigen::Vector3f(static_cast<float>(std::cos(turn) * v.x() + std::sin(turn) * v.z()), v.y(),
                          static_cast<float>(-std::sin(turn) * v.x() + std::cos(turn) * v.z()));
    const LinearOctree tree = LinearOctree::build(m, 0.001);
    const Charts charts = find_charts(tree, 0.0);
    for (std::size_t c = 0; c < charts.axes.size(); ++c) {
      const HeightMap map = build_height_map(tree.subset(charts.members(tree, static_cast<int>(c))), 0.001,
                                             0.003, nullptr, charts.axes[c]);
      // Along each row, between its first and last surface pixel: no empty pixel.
      std::size_t gaps = 0;
      for (int r = map.rows / 4; r < 3 * map.rows / 4; ++r) {
        const float* w = map.weight.data() + static_cast<std::size_t>(r) * static_cast<std::size_t>(map.cols);
        int first = map.cols, last = -1;
        for (int k = 0; k < map.cols; ++k)
          if (w[k] > 0.0f) first = std::min(first, k), last = k;
        for (int k = first; k < last; ++k) gaps += !(w[k] > 0.0f);
      }
      EXPECT_EQ(gaps, 0u) << "chart " << c;
    }
  }
}

}  // namespace
}  // namespace dentmark::detect
