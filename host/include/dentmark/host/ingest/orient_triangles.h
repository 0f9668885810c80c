#pragma once
// Consistent triangle winding. A mesh merged from several views or written by a tool
// that does not keep winding may have neighbouring triangles wound opposite ways; their
// normals then cancel in the octree's sums (eq. 1-3) and a dent reads as a bump where
// the winding is inverted. Here every edge-connected part is wound like most of its
// area, and parts that meet on one surface alike (a consistent mesh comes back untouched;
// the detector decides which side is out).

#include <cstddef>
#include <optional>

#include "dentmark/common/ingest/mesh.h"
#include "dentmark/common/ingest/mesh_view.h"

namespace dentmark::ingest {

struct OrientedMesh {
  Mesh mesh;                // the input's vertices; triangles rewound where they disagreed
  std::size_t flipped = 0;  // triangles rewound
  std::size_t parts = 0;    // edge-connected parts
};

// Whether two triangles leave some vertex along the same edge: neighbours wound opposite
// ways, or an edge of three or more triangles. One pass over the corners, about 16 bytes
// per triangle for the while.
bool has_opposed_neighbours(const MeshView& mesh);

// The vertex-connected parts with at least `min_triangles` triangles: views merged side
// by side, each consistent on its own, may still be wound opposite ways.
std::size_t large_parts(const MeshView& mesh, std::size_t min_triangles);

// Walks the triangles across their manifold edges (an edge shared by exactly two
// triangles); a triangle agrees with a neighbour when the two run the shared edge in
// opposite directions. Edges of three or more triangles, degenerate triangles, and two
// that run their edge the same way but face the same side (they overlap, folded onto
// each other) link nothing. Parts that share no edge but meet on one surface (overlapping or abutting,
// normals parallel or opposite, not the two sides of a sheet) are wound alike. Each part,
// or group of parts so linked, keeps the winding of the larger area of it. Returns
// nothing when all is consistent already.
std::optional<OrientedMesh> orient_consistently(const MeshView& mesh);

}  // namespace dentmark::ingest
