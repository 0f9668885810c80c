#include "coarse_defects.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "findings.h"

namespace dentmark::detect {
namespace {

// Union-find over vertices, by size, with path halving.
struct DisjointSets {
  std::vector<std::uint32_t> parent, size;
  explicit DisjointSets(std::size_t n) : parent(n), size(n, 1) {
    for (std::size_t i = 0; i < n; ++i) parent[i] = static_cast<std::uint32_t>(i);
  }
  std::uint32_t find(std::uint32_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  }
  void join(std::uint32_t a, std::uint32_t b) {
    a = find(a), b = find(b);
    if (a == b) return;
    if (size[a] < size[b]) std::swap(a, b);
    parent[b] = a, size[a] += size[b];
  }
};

}  // namespace

std::vector<VertexGroup> coherent_groups(const ingest::MeshView& mesh, const std::vector<float>& residual,
                                         const std::vector<std::uint8_t>& excluded, double sigma,
                                         double seed_sigmas, double member_sigmas) {
  const std::size_t n = mesh.vertex_count();
  const double member = member_sigmas * sigma, seed = seed_sigmas * sigma;
  // -1, 0, +1: the side a vertex stands out on (0: within member × σ, or no residual).
  std::vector<std::int8_t> side(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const float r = residual[i];
    if (std::isfinite(r) && std::abs(r) > member) side[i] = r > 0.0f ? 1 : -1;
  }
  DisjointSets sets(n);
  for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
    const auto tri = mesh.triangle(t);
    for (int e = 0; e < 3; ++e) {
      const std::uint32_t a = tri[static_cast<std::size_t>(e)],
                          b = tri[static_cast<std::size_t>((e + 1) % 3)];
      if (side[a] != 0 && side[a] == side[b]) sets.join(a, b);
    }
  }
  // Per root: its group's index, in the order of the groups' first vertices.
  std::vector<std::int32_t> index(n, -1);
  std::vector<VertexGroup> groups;
  std::vector<std::uint8_t> seeded, touches_excluded;
  for (std::size_t i = 0; i < n; ++i) {
    if (side[i] == 0) continue;
    const std::uint32_t root = sets.find(static_cast<std::uint32_t>(i));
    if (index[root] < 0) {
      index[root] = static_cast<std::int32_t>(groups.size());
      groups.push_back({{}, static_cast<std::uint32_t>(i), side[i]});
      seeded.push_back(0), touches_excluded.push_back(0);
    }
    const auto g = static_cast<std::size_t>(index[root]);
    VertexGroup& group = groups[g];
    group.vertices.push_back(static_cast<std::uint32_t>(i));
    if (std::abs(residual[i]) > std::abs(residual[group.apex])) group.apex = static_cast<std::uint32_t>(i);
    seeded[g] |= std::abs(residual[i]) > seed;
    touches_excluded[g] |= excluded[i] != 0;
  }
  std::vector<VertexGroup> kept;
  for (std::size_t g = 0; g < groups.size(); ++g)
    if (seeded[g] && !touches_excluded[g] && groups[g].vertices.size() >= 2)
      kept.push_back(std::move(groups[g]));
  return kept;
}

std::vector<std::uint8_t> near_mesh_boundary(const ingest::MeshView& mesh, int rings) {
  // Each undirected edge once per triangle; sorted, an edge seen once is on the boundary.
  std::vector<std::uint64_t> edges;
  edges.reserve(3 * mesh.triangle_count());
  for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
    const auto tri = mesh.triangle(t);
    for (int e = 0; e < 3; ++e) {
      const std::uint64_t a = tri[static_cast<std::size_t>(e)],
                          b = tri[static_cast<std::size_t>((e + 1) % 3)];
      edges.push_back(std::min(a, b) << 32 | std::max(a, b));
    }
  }
  std::sort(edges.begin(), edges.end());
  std::vector<std::uint8_t> near(mesh.vertex_count(), 0);
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i + 1;
    while (j < edges.size() && edges[j] == edges[i]) ++j;
    if (j - i == 1) near[edges[i] >> 32] = near[edges[i] & 0xffffffffu] = 1;
    i = j;
  }
  // Each ring: the vertices of the triangles that hold a vertex of the last.
  for (int ring = 0; ring < rings; ++ring) {
    std::vector<std::uint8_t> grown = near;
    for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
      const auto tri = mesh.triangle(t);
      if (near[tri[0]] || near[tri[1]] || near[tri[2]]) grown[tri[0]] = grown[tri[1]] = grown[tri[2]] = 1;
    }
    near.swap(grown);
  }
  return near;
}

Finding coarse_finding(const VertexGroup& group, const ingest::MeshView& mesh,
                       const std::vector<float>& residual, const Eigen::Vector3d& normal, double spacing,
                       double sigma, double detection_sigma) {
  const double height = residual[group.apex];
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  double weights = 0.0;
  int over_half = 0;
  for (const std::uint32_t i : group.vertices) {
    const double r = std::abs(static_cast<double>(residual[i]));
    position += r * mesh.vertex(i).cast<double>();
    weights += r;
    over_half += r >= 0.5 * std::abs(height);
  }
  Finding f;
  f.reason = "coherent vertex group (coarse scan)";
  f.pixels = 0;
  protocol::Defect& d = f.defect;
  d.defect_class = height < 0.0 ? protocol::DefectClass::kDent : protocol::DefectClass::kBump;
  d.position = position / weights;
  d.normal = normal;
  d.height = height;
  d.diameter = 4.0 * spacing * std::sqrt(static_cast<double>(over_half) / std::numbers::pi);
  d.area = disc_area(d.diameter);
  const double snr = std::abs(height) / sigma;
  d.score = score_of(snr, detection_sigma);
  return f;
}

}  // namespace dentmark::detect
