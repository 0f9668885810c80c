#include "dentmark/host/ingest/orient_triangles.h"

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <vector>

namespace dentmark::ingest {
namespace {

constexpr std::uint8_t kUnvisited = 2;

// One corner of a triangle, filed under its vertex: the triangle, and the vertices after
// and before this one in its winding (the edges out of and into the vertex).
struct Corner {
  std::uint32_t triangle, next, prev;
};

// Something filed under each corner's vertex, in compressed rows: vertex v's entries are
// entries[first[v] .. first[v + 1]). make(t, k, tri) gives the entry for corner k of t.
template <class Entry, class Make>
void file_by_vertex(const MeshView& mesh, std::vector<std::size_t>& first, std::vector<Entry>& entries,
                    Make make) {
  const std::size_t n = mesh.triangle_count();
  first.assign(mesh.vertex_count() + 1, 0);
  for (std::size_t t = 0; t < n; ++t)
    for (const std::uint32_t v : mesh.triangle(t)) ++first[v + 1];
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) first[v + 1] += first[v];
  entries.resize(first.back());
  // first[v] walks through row v as it fills, ending where row v + 1 starts.
  for (std::size_t t = 0; t < n; ++t) {
    const auto tri = mesh.triangle(t);
    for (int k = 0; k < 3; ++k) entries[first[tri[k]]++] = make(t, k, tri);
  }
  for (std::size_t v = mesh.vertex_count(); v > 0; --v) first[v] = first[v - 1];
  first[0] = 0;
}

float area(const MeshView& mesh, const std::array<std::uint32_t, 3>& tri) {
  const Eigen::Vector3f p = mesh.vertex(tri[0]);
  return 0.5f * (mesh.vertex(tri[1]) - p).cross(mesh.vertex(tri[2]) - p).norm();
}

}  // namespace

bool has_opposed_neighbours(const MeshView& mesh) {
  // The vertex after each corner: the edge leaving its vertex. Consistent neighbours
  // leave a shared vertex along different edges.
  std::vector<std::size_t> first;
  std::vector<std::uint32_t> next;
  file_by_vertex(mesh, first, next, [](std::size_t, int k, const std::array<std::uint32_t, 3>& tri) {
    return tri[(k + 1) % 3];
  });
  const std::size_t vertices = mesh.vertex_count();
  bool twice = false;
#pragma omp parallel for schedule(static) reduction(|| : twice)
  for (std::size_t v = 0; v < vertices; ++v)
    for (std::size_t i = first[v]; i < first[v + 1]; ++i)
      for (std::size_t j = i + 1; j < first[v + 1]; ++j)
        twice = twice || (next[i] == next[j] && next[i] != v);
  return twice;
}

std::optional<OrientedMesh> orient_consistently(const MeshView& mesh) {
  const std::size_t n = mesh.triangle_count();
  struct {
    std::vector<std::size_t> first;
    std::vector<Corner> corners;
  } around;
  file_by_vertex(mesh, around.first, around.corners,
                 [](std::size_t t, int k, const std::array<std::uint32_t, 3>& tri) {
                   return Corner{static_cast<std::uint32_t>(t), tri[(k + 1) % 3], tri[(k + 2) % 3]};
                 });

  // flip[t]: 0 keep, 1 rewind, kUnvisited not reached yet.
  std::vector<std::uint8_t> flip(n, kUnvisited);
  std::vector<std::uint32_t> part;  // the current part's triangles, in the order reached
  std::size_t parts = 0, flipped = 0;
  for (std::size_t seed = 0; seed < n; ++seed) {
    if (flip[seed] != kUnvisited) continue;
    ++parts;
    part.assign(1, static_cast<std::uint32_t>(seed));
    flip[seed] = 0;
    double area_kept = 0.0, area_flipped = 0.0;
    for (std::size_t i = 0; i < part.size(); ++i) {
      const std::uint32_t t = part[i];
      const auto tri = mesh.triangle(t);
      (flip[t] ? area_flipped : area_kept) += area(mesh, tri);
      for (int k = 0; k < 3; ++k) {
        // Edge a -> b of t: its other triangle, if it is the only one, runs it b -> a
        // when wound like t, a -> b when wound the other way.
        const std::uint32_t a = tri[k], b = tri[(k + 1) % 3];
        if (a == b) continue;
        std::uint32_t other = 0, others = 0, same_way = 0;
        for (std::size_t j = around.first[a]; j < around.first[a + 1]; ++j) {
          const Corner& c = around.corners[j];
          if (c.triangle == t || (c.next != b && c.prev != b)) continue;
          other = c.triangle, same_way = c.next == b, ++others;
        }
        if (others != 1 || flip[other] != kUnvisited) continue;
        flip[other] = static_cast<std::uint8_t>(flip[t] ^ same_way);
        part.push_back(other);
      }
    }
    // The part keeps the winding most of its area has.
    const bool invert = area_flipped > area_kept;
    for (const std::uint32_t t : part) {
      if (invert) flip[t] ^= 1;
      flipped += flip[t];
    }
  }
  if (flipped == 0) return std::nullopt;

  OrientedMesh out;
  out.flipped = flipped;
  out.parts = parts;
  out.mesh.vertices.resize(mesh.vertex_count());
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) out.mesh.vertices[v] = mesh.vertex(v);
  out.mesh.triangles.resize(n);
  for (std::size_t t = 0; t < n; ++t) {
    auto tri = mesh.triangle(t);
    if (flip[t]) std::swap(tri[1], tri[2]);
    out.mesh.triangles[t] = tri;
  }
  return out;
}

}  // namespace dentmark::ingest
