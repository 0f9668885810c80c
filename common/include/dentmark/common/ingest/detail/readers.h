#pragma once
// Per-format readers behind read_mesh(). Each fills vertices (file units, scaled to
// metres by the caller) and triangles; they throw IngestError naming file and position.

#include <optional>
#include <string>
#include <string_view>

#include "dentmark/common/ingest/mesh.h"
#include "dentmark/common/ingest/mesh_view.h"

namespace dentmark::ingest::detail {

Mesh read_ply(const std::string& path, std::string_view bytes);
Mesh read_obj(const std::string& path, std::string_view bytes);
Mesh read_stl(const std::string& path, std::string_view bytes);
Mesh read_xyz(const std::string& path, std::string_view bytes);
Mesh read_pcd(const std::string& path, std::string_view bytes);

// Vertices at exactly the same position made one (the first of them, in file order), and
// the triangles renumbered: STL's facets each keep their own three corners, so without
// this no triangle shares an edge with its neighbour (weld_vertices.cpp).
void weld_vertices(Mesh& mesh);

// A binary little-endian PLY in the usual scanner layout (float x, y, z consecutive in the
// vertex record; a trailing face element of uchar 3 and 32-bit indices) as a view of the
// bytes themselves, after a parallel check of every face and coordinate; nullopt for any
// other layout or content, which read_ply then reads (and reports). `scale`: to metres.
std::optional<MeshView> ply_in_place(const std::string& path, std::string_view bytes, float scale);

}  // namespace dentmark::ingest::detail
