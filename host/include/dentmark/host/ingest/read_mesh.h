#pragma once
// Reads a scan (PLY ascii/binary LE/BE, OBJ, STL ascii/binary, XYZ text, PCD ascii/binary/
// binary_compressed) into a Mesh. Point clouds (PLY without faces, XYZ, PCD) are meshed in the sensor's view
// (2.5D).

#include <cstddef>
#include <functional>
#include <memory>
#include <string>

#include "dentmark/host/ingest/mesh.h"
#include "dentmark/host/ingest/mesh_view.h"

namespace dentmark::ingest {

enum class Format { kAuto, kPly, kObj, kStl, kXyz, kPcd };

struct ReadOptions {
  double scale_to_m = 1.0;  // file units -> metres (mm files: 0.001)
  Format format = Format::kAuto;
  // Called with the fraction done (0..1) while reading big files; may be empty.
  std::function<void(double)> progress;
};

// Throws IngestError naming the file and the line or byte offset.
Mesh read_mesh(const std::string& path, const ReadOptions& options = {});

// A scan ready for detection. A binary PLY in the usual scanner layout is used in place
// in the mapped file (checked, not copied); any other file is read into a Mesh. Copies
// share the memory behind `mesh`.
struct Scan {
  MeshView mesh;
  std::size_t input_points = 0;         // vertices / points in the file
  std::size_t dropped_faces = 0;        // faces with < 3 corners or non-finite corners
  std::size_t nonfinite_vertices = 0;   // vertices without a position: NaN/Inf, or a cloud's (0, 0, 0)
  bool from_point_cloud = false;        // a point cloud, meshed here
  std::size_t cloud_charts = 0;         // a cloud that folds over in the view: meshed in these charts
  bool in_place = false;                // `mesh` is the file's own bytes
  std::shared_ptr<const void> storage;  // the mapped file or the Mesh behind `mesh`
};

// Throws IngestError naming the file and the line or byte offset.
Scan open_scan(const std::string& path, const ReadOptions& options = {});

// Format from the file name's extension (case-insensitive); kAuto if unknown. A file with
// no known extension is told by its content (PLY, PCD or STL); anything else is refused
// as an unknown format.
Format format_from_path(const std::string& path);

}  // namespace dentmark::ingest
