#pragma once
// Binary little-endian PLY output of a mesh, optionally with per-vertex colours.
// Written to a temporary file and renamed, so a failure never leaves half a file.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "dentmark/common/ingest/mesh_view.h"

namespace dentmark::ingest {

// colours: empty, or one RGB per vertex. Throws IngestError on I/O failure.
void write_ply(const std::string& path, const MeshView& mesh,
               const std::vector<std::array<std::uint8_t, 3>>& colours = {});

}  // namespace dentmark::ingest
