// Consistent winding (orient_triangles.h): meshes whose triangles were rewound at random,
// in halves or in patches come back wound one way throughout; consistent meshes and
// parts wound each their own way are left alone.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <utility>

#include "dentmark/host/ingest/orient_triangles.h"

namespace dentmark::ingest {
namespace {

// An n x n grid of vertices on a gently curved sheet, 1 mm apart, offset by `x0` along x;
// its triangles wound towards +z.
void add_sheet(Mesh& mesh, int n, float x0 = 0.0f) {
  const auto base = static_cast<std::uint32_t>(mesh.vertices.size());
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const float x = x0 + 1e-3f * i, y = 1e-3f * j;
      mesh.vertices.emplace_back(x, y, 0.5f + 2.0f * (x * x + y * y));
    }
  const auto at = [&](int i, int j) { return base + static_cast<std::uint32_t>(j * n + i); };
  for (int j = 0; j + 1 < n; ++j)
    for (int i = 0; i + 1 < n; ++i) {
      mesh.triangles.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      mesh.triangles.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
}

// A closed surface: an octahedron whose faces are split `levels` times, on a unit sphere.
Mesh sphere(int levels) {
  Mesh m;
  m.vertices = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  m.triangles = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> middle;
    const auto mid = [&](std::uint32_t a, std::uint32_t b) {
      const auto key = std::minmax(a, b);
      auto [it, added] = middle.try_emplace(key, static_cast<std::uint32_t>(m.vertices.size()));
      if (added) m.vertices.push_back((m.vertices[a] + m.vertices[b]).normalized());
      return it->second;
    };
    std::vector<std::array<std::uint32_t, 3>> finer;
    for (const auto& [a, b, c] : m.triangles) {
      const std::uint32_t ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
      finer.push_back({a, ab, ca});
      finer.push_back({ab, b, bc});
      finer.push_back({ca, bc, c});
      finer.push_back({ab, bc, ca});
    }
    m.triangles = std::move(finer);
  }
  return m;
}

Eigen::Vector3f normal(const Mesh& m, const std::array<std::uint32_t, 3>& t) {
  return (m.vertices[t[1]] - m.vertices[t[0]]).cross(m.vertices[t[2]] - m.vertices[t[0]]);
}

// Every edge shared by two triangles is run once each way.
bool consistent(const Mesh& m) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> runs;
  for (const auto& t : m.triangles)
    for (int k = 0; k < 3; ++k) ++runs[{t[k], t[(k + 1) % 3]}];
  for (const auto& [edge, count] : runs)
    if (count > 1) return false;
  return true;
}

// The same corners, in the same or in reversed cyclic order.
bool same_triangle(std::array<std::uint32_t, 3> a, std::array<std::uint32_t, 3> b) {
  for (int r = 0; r < 3; ++r) {
    if (a == b) return true;
    std::swap(b[1], b[2]);
    if (a == b) return true;
    std::swap(b[1], b[2]);
    std::rotate(b.begin(), b.begin() + 1, b.end());
  }
  return false;
}

std::size_t rewind_at_random(Mesh& m, double share, std::mt19937& rng) {
  std::bernoulli_distribution pick(share);
  std::size_t rewound = 0;
  for (auto& t : m.triangles)
    if (pick(rng)) std::swap(t[1], t[2]), ++rewound;
  return rewound;
}

TEST(OrientTriangles, AConsistentMeshIsLeftAlone) {
  Mesh sheet;
  add_sheet(sheet, 40);
  EXPECT_FALSE(has_opposed_neighbours(sheet));
  EXPECT_FALSE(orient_consistently(sheet).has_value());
  const Mesh ball = sphere(3);
  EXPECT_FALSE(has_opposed_neighbours(ball));
  EXPECT_FALSE(orient_consistently(ball).has_value());
  EXPECT_FALSE(has_opposed_neighbours(Mesh{}));
  EXPECT_FALSE(orient_consistently(Mesh{}).has_value());
}

TEST(OrientTriangles, RandomlyRewoundSheetsComeBackWoundLikeMostOfThem) {
  std::mt19937 rng(5);
  for (const double share : {0.002, 0.1, 0.3, 0.7, 0.95}) {
    SCOPED_TRACE(share);
    Mesh m;
    add_sheet(m, 60);
    const Mesh original = m;
    const std::size_t rewound = rewind_at_random(m, share, rng);
    std::vector<std::size_t> order(m.triangles.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::shuffle(order.begin(), order.end(), rng);  // in any order
    Mesh shuffled = m;
    for (std::size_t i = 0; i < order.size(); ++i) shuffled.triangles[i] = m.triangles[order[i]];

    ASSERT_TRUE(has_opposed_neighbours(shuffled));
    const auto oriented = orient_consistently(shuffled);
    ASSERT_TRUE(oriented.has_value());
    const Mesh& out = oriented->mesh;
    EXPECT_EQ(out.vertices, shuffled.vertices);
    ASSERT_EQ(out.triangles.size(), shuffled.triangles.size());
    for (std::size_t i = 0; i < out.triangles.size(); ++i)
      ASSERT_TRUE(same_triangle(out.triangles[i], shuffled.triangles[i])) << i;
    EXPECT_TRUE(consistent(out));
    EXPECT_FALSE(has_opposed_neighbours(out));
    // Wound the way most of the triangles (all but equal in area) were.
    const float up = share < 0.5 ? 1.0f : -1.0f;
    for (const auto& t : out.triangles) ASSERT_GT(up * normal(out, t).z(), 0.0f);
    EXPECT_EQ(oriented->flipped, share < 0.5 ? rewound : m.triangles.size() - rewound);
    EXPECT_EQ(oriented->parts, 1u);
  }
}

TEST(OrientTriangles, AClosedSurfaceRewoundAtRandomIsWoundOneWayRoundAgain) {
  std::mt19937 rng(9);
  for (int trial = 0; trial < 5; ++trial) {
    Mesh m = sphere(4);
    rewind_at_random(m, 0.4, rng);
    const auto oriented = orient_consistently(m);
    ASSERT_TRUE(oriented.has_value());
    EXPECT_TRUE(consistent(oriented->mesh));
    // All outwards (most were) on a convex ball.
    for (const auto& t : oriented->mesh.triangles)
      ASSERT_GT(normal(oriented->mesh, t).dot(oriented->mesh.vertices[t[0]]), 0.0f);
  }
}

TEST(OrientTriangles, EachPartKeepsItsOwnWinding) {
  // Two sheets apart, one wound towards +z and one towards -z: each is consistent, and
  // which side is out is the detector's business.
  Mesh m;
  add_sheet(m, 20);
  const std::size_t first = m.triangles.size();
  add_sheet(m, 20, 0.1f);
  for (std::size_t i = first; i < m.triangles.size(); ++i) std::swap(m.triangles[i][1], m.triangles[i][2]);
  EXPECT_FALSE(has_opposed_neighbours(m));
  EXPECT_FALSE(orient_consistently(m).has_value());

  // Rewound in patches, each part comes back wound as most of it was.
  std::mt19937 rng(2);
  rewind_at_random(m, 0.2, rng);
  const auto oriented = orient_consistently(m);
  ASSERT_TRUE(oriented.has_value());
  EXPECT_EQ(oriented->parts, 2u);
  for (std::size_t i = 0; i < m.triangles.size(); ++i)
    ASSERT_GT((i < first ? 1.0f : -1.0f) * normal(oriented->mesh, oriented->mesh.triangles[i]).z(), 0.0f)
        << i;
}

// A sheet like add_sheet's, n x n vertices from (x0, y0), lifted by dz; wound towards
// +z, or towards -z.
void add_plane(Mesh& mesh, int n, float x0, float y0, float dz, bool up) {
  const auto base = static_cast<std::uint32_t>(mesh.vertices.size());
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) mesh.vertices.emplace_back(x0 + 1e-3f * i, y0 + 1e-3f * j, 0.5f + dz);
  const auto at = [&](int i, int j) { return base + static_cast<std::uint32_t>(j * n + i); };
  for (int j = 0; j + 1 < n; ++j)
    for (int i = 0; i + 1 < n; ++i) {
      std::array<std::uint32_t, 3> a{at(i, j), at(i + 1, j), at(i + 1, j + 1)},
          b{at(i, j), at(i + 1, j + 1), at(i, j + 1)};
      if (!up) std::swap(a[1], a[2]), std::swap(b[1], b[2]);
      mesh.triangles.push_back(a);
      mesh.triangles.push_back(b);
    }
}

TEST(OrientTriangles, ViewsMergedWithoutSharedEdgesAreWoundAlike) {
  // Three views of one plane, each on vertices of its own: two overlap the first by 5 mm
  // (one 10 µm off it, as registration leaves them), one abuts it across a 0.4 mm gap;
  // the smaller two are wound the other way.
  Mesh m;
  add_plane(m, 50, 0.0f, 0.0f, 0.0f, true);
  const std::size_t second = m.triangles.size();
  add_plane(m, 30, 0.044f, 0.01f, 1e-5f, false);
  add_plane(m, 30, 0.01f, 0.0494f, 0.0f, false);
  EXPECT_FALSE(has_opposed_neighbours(m));
  EXPECT_EQ(large_parts(m, 100), 3u);
  const auto oriented = orient_consistently(m);
  ASSERT_TRUE(oriented.has_value());
  EXPECT_EQ(oriented->flipped, m.triangles.size() - second);
  for (const auto& t : oriented->mesh.triangles) ASSERT_GT(normal(oriented->mesh, t).z(), 0.0f);
}

TEST(OrientTriangles, TheTwoSidesOfASheetStayWoundOutwards) {
  // The outer and inner skin of a 0.8 mm sheet, both scanned, each wound outwards:
  // opposite normals on two planes, not one surface wound two ways.
  Mesh m;
  add_plane(m, 40, 0.0f, 0.0f, 0.0f, true);
  add_plane(m, 40, 0.0f, 0.0f, -8e-4f, false);
  EXPECT_FALSE(orient_consistently(m).has_value());
}

TEST(OrientTriangles, TrianglesFoldedOntoTheirNeighboursAreNoEvidence) {
  // Along one border of a sheet, triangles on the border's edges that lie back over the
  // sheet (two triangulations meeting and overlapping): each runs its edge the way the
  // sheet's triangle does, yet faces the same side. They are not wound the wrong way.
  Mesh m;
  add_plane(m, 20, 0.0f, 0.0f, 0.0f, true);
  for (std::uint32_t i = 0; i + 1 < 20; ++i) {
    const auto v = static_cast<std::uint32_t>(m.vertices.size());
    m.vertices.emplace_back(1e-3f * (static_cast<float>(i) + 0.5f), 0.6e-3f, 0.5f);
    m.triangles.push_back({i, i + 1, v});
  }
  EXPECT_TRUE(has_opposed_neighbours(m));  // (worth the walk)
  EXPECT_FALSE(orient_consistently(m).has_value());
}

TEST(OrientTriangles, FinsOnOneEdgeAndDegenerateTrianglesLinkNothing) {
  // Three triangles on one edge (a non-manifold fin), and a triangle with a repeated
  // corner, beside a sheet: nothing to rewind, nothing read out of bounds.
  Mesh m;
  add_sheet(m, 10);
  const auto v = static_cast<std::uint32_t>(m.vertices.size());
  m.vertices.insert(m.vertices.end(), {{1, 0, 0}, {1, 1, 0}, {2, 0, 1}, {2, 0, -1}, {0, 0, 2}});
  m.triangles.push_back({v, v + 1, v + 2});
  m.triangles.push_back({v, v + 1, v + 3});
  m.triangles.push_back({v + 1, v, v + 4});
  m.triangles.push_back({0, 0, 1});
  EXPECT_TRUE(has_opposed_neighbours(m));  // the fins run v -> v + 1 twice
  const auto oriented = orient_consistently(m);
  EXPECT_FALSE(oriented.has_value());
}

}  // namespace
}  // namespace dentmark::ingest
