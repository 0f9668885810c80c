#pragma once
// Reads a scan (PLY ascii/binary LE/BE, OBJ, STL ascii/binary, XYZ text) into a Mesh.
// Point clouds (PLY without faces, XYZ) are meshed in the sensor's view (2.5D).

#include <functional>
#include <string>

#include "dentmark/host/ingest/mesh.h"

namespace dentmark::ingest {

enum class Format { kAuto, kPly, kObj, kStl, kXyz };

struct ReadOptions {
  double scale_to_m = 1.0;  // file units -> metres (mm files: 0.001)
  Format format = Format::kAuto;
  // Called with the fraction done (0..1) while reading big files; may be empty.
  std::function<void(double)> progress;
};

// Throws IngestError naming the file and the line or byte offset.
Mesh read_mesh(const std::string& path, const ReadOptions& options = {});

// Format from the file name's extension (case-insensitive); kAuto if unknown.
Format format_from_path(const std::string& path);

}  // namespace dentmark::ingest
