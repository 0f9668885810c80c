#include "dentmark/host/ingest/orient_triangles.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <numeric>
#include <utility>
#include <vector>

namespace dentmark::ingest {
namespace {

constexpr std::uint8_t kUnvisited = 2;
// Two parts' surfaces closer than this along their normal are one surface: views of it
// registered to within a tenth of a millimetre, not the two sides of a body panel's
// sheet (0.6 mm and more).
constexpr double kOnePlane = 0.3e-3;

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

// Twice the area times the unit normal, as the triangle is wound.
Eigen::Vector3f area_normal(const MeshView& mesh, const std::array<std::uint32_t, 3>& tri) {
  const Eigen::Vector3f p = mesh.vertex(tri[0]);
  return (mesh.vertex(tri[1]) - p).cross(mesh.vertex(tri[2]) - p);
}

float area(const MeshView& mesh, const std::array<std::uint32_t, 3>& tri) {
  return 0.5f * area_normal(mesh, tri).norm();
}

// Union-find whose links carry a parity: find(x) gives x's root and whether x is wound
// the other way from it.
class ParityUnion {
 public:
  explicit ParityUnion(std::size_t n) : parent_(n), parity_(n, 0) {
    std::iota(parent_.begin(), parent_.end(), 0);
  }
  std::pair<std::size_t, std::uint8_t> find(std::size_t x) {
    std::uint8_t p = 0;
    std::size_t r = x;
    while (parent_[r] != r) p ^= parity_[r], r = parent_[r];
    // Path compression with the parities folded in.
    std::uint8_t q = p;
    while (parent_[x] != x) {
      const std::size_t next = parent_[x];
      const std::uint8_t here = parity_[x];
      parent_[x] = r, parity_[x] = q;
      q ^= here, x = next;
    }
    return {r, p};
  }
  // Joins a and b with b's winding = a's XOR `odd`; false when they were joined already.
  bool join(std::size_t a, std::size_t b, std::uint8_t odd) {
    const auto [ra, pa] = find(a);
    const auto [rb, pb] = find(b);
    if (ra == rb) return false;
    parent_[rb] = ra, parity_[rb] = static_cast<std::uint8_t>(pa ^ pb ^ odd);
    return true;
  }

 private:
  std::vector<std::size_t> parent_;
  std::vector<std::uint8_t> parity_;
};

// Parts that share no edge (views merged side by side or overlapping, pieces joined at a
// vertex) but lie on one surface: where two parts meet in a cell of `cell` metres, on one
// plane (their centroids within kOnePlane and a quarter cell along the normal: not the
// two sides of a sheet) with parallel or opposite normals, they should be wound alike.
// Each group of parts so linked, strongest links first, is wound like the larger area
// of it.
// part[t]: t's edge-connected part; flip[t]: its winding within the part (0 or 1);
// part_area[p]: part p's area.
// Returns per part whether to rewind it as a whole.
std::vector<std::uint8_t> agree_across_parts(const MeshView& mesh, const std::vector<std::uint32_t>& part,
                                             const std::vector<std::uint8_t>& flip,
                                             const std::vector<double>& part_area, double cell) {
  constexpr std::size_t kMinPartTriangles = 8;  // fewer give no normal to speak of
  const std::size_t n = mesh.triangle_count(), parts = part_area.size();
  std::vector<std::size_t> size(parts, 0);
  for (std::size_t t = 0; t < n; ++t) ++size[part[t]];

  // (cell, part) per triangle of the parts large enough, sorted: each cell's parts together.
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  for (std::size_t t = 0; t < n; ++t)
    for (const std::uint32_t v : mesh.triangle(t))
      if (const Eigen::Vector3f p = mesh.vertex(v); p.allFinite()) lo = lo.cwiseMin(p);
  struct Entry {
    std::uint64_t cell;
    std::uint32_t part, triangle;
    bool operator<(const Entry& o) const { return cell != o.cell ? cell < o.cell : part < o.part; }
  };
  std::vector<Entry> entries;
  for (std::size_t t = 0; t < n; ++t) {
    if (size[part[t]] < kMinPartTriangles) continue;
    const auto tri = mesh.triangle(t);
    const Eigen::Vector3f c = (mesh.vertex(tri[0]) + mesh.vertex(tri[1]) + mesh.vertex(tri[2])) / 3.0f;
    const Eigen::Vector3d q = ((c - lo).cast<double>() / cell).array().floor();
    const auto axis = [](double x) {  // 21 bits; NaN (a corner without a position) as 0
      return x >= 0.0 ? static_cast<std::uint64_t>(std::min(x, 2097151.0)) : std::uint64_t{0};
    };
    entries.push_back(
        {axis(q.x()) << 42 | axis(q.y()) << 21 | axis(q.z()), part[t], static_cast<std::uint32_t>(t)});
  }
  std::sort(entries.begin(), entries.end());

  // Per cell, each part's area-weighted normal and centroid; per pair of parts meeting on
  // one plane, the area over which they agree (+) or disagree (-).
  struct Piece {
    std::uint32_t part;
    Eigen::Vector3d sum_an, sum_ac;
    double area;
  };
  std::map<std::pair<std::uint32_t, std::uint32_t>, double> evidence;
  std::vector<Piece> pieces;
  for (std::size_t i = 0; i < entries.size();) {
    std::size_t j = i;
    pieces.clear();
    for (; j < entries.size() && entries[j].cell == entries[i].cell; ++j) {
      const auto tri = mesh.triangle(entries[j].triangle);
      Eigen::Vector3d an = 0.5 * area_normal(mesh, tri).cast<double>();
      if (flip[entries[j].triangle]) an = -an;
      const double a = an.norm();
      const Eigen::Vector3d c =
          ((mesh.vertex(tri[0]) + mesh.vertex(tri[1]) + mesh.vertex(tri[2])) / 3.0f).cast<double>();
      if (pieces.empty() || pieces.back().part != entries[j].part)
        pieces.push_back({entries[j].part, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 0.0});
      pieces.back().sum_an += an, pieces.back().sum_ac += a * c, pieces.back().area += a;
    }
    i = j;
    for (std::size_t p = 0; p < pieces.size(); ++p)
      for (std::size_t q = p + 1; q < pieces.size(); ++q) {
        const Piece &a = pieces[p], &b = pieces[q];
        if (a.sum_an.norm() < 0.5 * a.area || b.sum_an.norm() < 0.5 * b.area) continue;  // folded in the cell
        const Eigen::Vector3d na = a.sum_an.normalized(), nb = b.sum_an.normalized();
        const double d = na.dot(nb);
        if (std::abs(d) < 0.7) continue;
        const Eigen::Vector3d offset = a.sum_ac / a.area - b.sum_ac / b.area;
        if (std::abs(offset.dot(na)) > std::min(0.25 * cell, kOnePlane)) continue;  // two sides of a sheet
        evidence[{a.part, b.part}] += (d > 0 ? 1.0 : -1.0) * std::min(a.area, b.area);
      }
  }

  // Strongest links first; a link that closes a loop is outvoted by the stronger ones.
  std::vector<std::pair<double, std::pair<std::uint32_t, std::uint32_t>>> links;
  for (const auto& [pq, e] : evidence) links.push_back({e, pq});
  std::sort(links.begin(), links.end(),
            [](const auto& a, const auto& b) { return std::abs(a.first) > std::abs(b.first); });
  ParityUnion groups(parts);
  for (const auto& [e, pq] : links) groups.join(pq.first, pq.second, e < 0 ? 1 : 0);

  // Each group wound like the larger area of it.
  std::vector<double> area_kept(parts, 0.0), area_rewound(parts, 0.0);
  std::vector<std::uint8_t> parity(parts);
  std::vector<std::size_t> root(parts);
  for (std::size_t p = 0; p < parts; ++p) {
    std::tie(root[p], parity[p]) = groups.find(p);
    (parity[p] ? area_rewound : area_kept)[root[p]] += part_area[p];
  }
  std::vector<std::uint8_t> rewind(parts);
  for (std::size_t p = 0; p < parts; ++p)
    rewind[p] = static_cast<std::uint8_t>(parity[p] ^ (area_rewound[root[p]] > area_kept[root[p]] ? 1 : 0));
  return rewind;
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

std::size_t large_parts(const MeshView& mesh, std::size_t min_triangles) {
  ParityUnion parts(mesh.vertex_count());  // (no parities here: each triangle joins its corners)
  for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
    const auto tri = mesh.triangle(t);
    parts.join(tri[0], tri[1], 0), parts.join(tri[0], tri[2], 0);
  }
  std::vector<std::uint32_t> triangles(mesh.vertex_count(), 0);
  for (std::size_t t = 0; t < mesh.triangle_count(); ++t) ++triangles[parts.find(mesh.triangle(t)[0]).first];
  return static_cast<std::size_t>(
      std::count_if(triangles.begin(), triangles.end(), [&](std::uint32_t c) { return c >= min_triangles; }));
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
  std::vector<std::uint32_t> part_of(n);
  std::vector<std::uint32_t> part;  // the current part's triangles, in the order reached
  std::vector<double> part_area;    // per part
  double edge_sum = 0.0;            // for the cells of agree_across_parts: the mean edge
  for (std::size_t seed = 0; seed < n; ++seed) {
    if (flip[seed] != kUnvisited) continue;
    const auto this_part = static_cast<std::uint32_t>(part_area.size());
    part.assign(1, static_cast<std::uint32_t>(seed));
    flip[seed] = 0;
    double area_kept = 0.0, area_flipped = 0.0;
    for (std::size_t i = 0; i < part.size(); ++i) {
      const std::uint32_t t = part[i];
      const auto tri = mesh.triangle(t);
      part_of[t] = this_part;
      (flip[t] ? area_flipped : area_kept) += area(mesh, tri);
      edge_sum += (mesh.vertex(tri[1]) - mesh.vertex(tri[0])).norm();
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
        // Run the same way yet facing the same side, the two overlap (views' or charts'
        // triangulations meeting) rather than lie side by side: no evidence either way.
        if (same_way && area_normal(mesh, tri).dot(area_normal(mesh, mesh.triangle(other))) > 0.0f) continue;
        flip[other] = static_cast<std::uint8_t>(flip[t] ^ same_way);
        part.push_back(other);
      }
    }
    // The part keeps the winding most of its area has.
    if (area_flipped > area_kept)
      for (const std::uint32_t t : part) flip[t] ^= 1;
    part_area.push_back(area_kept + area_flipped);
  }
  if (const double cell = 3.0 * edge_sum / static_cast<double>(n);
      part_area.size() > 1 && cell > 0.0 && std::isfinite(cell)) {
    const std::vector<std::uint8_t> rewind = agree_across_parts(mesh, part_of, flip, part_area, cell);
    for (std::size_t t = 0; t < n; ++t) flip[t] ^= rewind[part_of[t]];
  }
  std::size_t flipped = 0;
  for (const std::uint8_t f : flip) flipped += f;
  if (flipped == 0) return std::nullopt;

  OrientedMesh out;
  out.flipped = flipped;
  out.parts = part_area.size();
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
