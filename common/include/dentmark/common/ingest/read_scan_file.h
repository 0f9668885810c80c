#pragma once
// Reads a scan file (PLY ascii/binary LE/BE, OBJ, STL ascii/binary, XYZ text, PCL's PCD
// ascii/binary/binary_compressed) as the
// scanner delivered it: vertices in metres and the faces the file stores, none for a
// point cloud. Meshing a cloud for detection is the host's (host/ingest/read_mesh.h);
// the edge's scanner calibration needs only the points.

#include <functional>
#include <string>
#include <string_view>

#include "dentmark/common/ingest/mesh.h"

namespace dentmark::ingest {

enum class Format { kAuto, kPly, kObj, kStl, kXyz, kPcd };

struct ReadOptions {
  double scale_to_m = 1.0;  // file units -> metres (mm files: 0.001)
  Format format = Format::kAuto;
  // Called with the fraction done (0..1) while reading big files; may be empty.
  std::function<void(double)> progress;
};

// Format from the file name's extension (case-insensitive); kAuto if unknown. A file with
// no known extension is told by its content (PLY, PCD or STL); anything else is refused
// as an unknown format.
Format format_from_path(const std::string& path);

// The file's vertices in metres (non-finite ones, and a cloud's (0, 0, 0) points, set to
// NaN and counted) and its faces (those using a non-finite vertex dropped; a triangle
// soup's coincident corners welded). A file without faces must hold at least 3 usable
// points. Throws IngestError naming the file and the line or byte offset.
Mesh read_scan_file(const std::string& path, const ReadOptions& options = {});

namespace detail {
// The steps of read_scan_file on a file already in memory, for the host's in-place reader.
void check_scale(const std::string& path, const ReadOptions& options);
Format resolve_format(const std::string& path, std::string_view bytes, const ReadOptions& options);
Mesh read_scan_bytes(const std::string& path, std::string_view bytes, Format format,
                     const ReadOptions& options);
// Triangles that keep their own corners (a PLY or OBJ written from STL, say).
bool is_triangle_soup(std::size_t vertices, std::size_t triangles);
}  // namespace detail

}  // namespace dentmark::ingest
