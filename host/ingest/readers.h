#pragma once
// Per-format readers behind read_mesh(). Each fills vertices (file units, scaled to
// metres by the caller) and triangles; they throw IngestError naming file and position.

#include <string>
#include <string_view>

#include "dentmark/host/ingest/mesh.h"

namespace dentmark::ingest::detail {

Mesh read_ply(const std::string& path, std::string_view bytes);
Mesh read_obj(const std::string& path, std::string_view bytes);
Mesh read_stl(const std::string& path, std::string_view bytes);
Mesh read_xyz(const std::string& path, std::string_view bytes);

}  // namespace dentmark::ingest::detail
