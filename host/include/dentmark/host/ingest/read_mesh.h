#pragma once
// Reads a scan (PLY ascii/binary LE/BE, OBJ, STL ascii/binary, XYZ text) into a Mesh.
// Point clouds (PLY without faces, XYZ) are meshed in the sensor's view (2.5D).

#include <cstddef>
#include <functional>
#include <memory>
#include <string>

#include "dentmark/common/ingest/mesh.h"
#include "dentmark/common/ingest/mesh_view.h"
#include "dentmark/common/ingest/read_scan_file.h"

namespace dentmark::ingest {

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

}  // namespace dentmark::ingest
