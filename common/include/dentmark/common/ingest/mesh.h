#pragma once
// A triangle mesh as the scanner delivered it, in metres, in the scan's frame ('sls').
// Vertices are float: 0.1 µm resolution over 2 m, half the memory of double.

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace dentmark::ingest {

struct Mesh {
  std::vector<Eigen::Vector3f> vertices;                // m
  std::vector<std::array<std::uint32_t, 3>> triangles;  // indices into vertices
  bool from_point_cloud = false;                        // a point cloud, meshed here
  std::size_t cloud_charts = 0;        // a cloud that folds over in the sensor's view: meshed in these charts
  std::size_t input_points = 0;        // vertices / points in the file
  std::size_t dropped_faces = 0;       // faces with < 3 corners or non-finite corners
  std::size_t nonfinite_vertices = 0;  // vertices without a position: NaN/Inf, or a cloud's (0, 0, 0)
};

// A malformed or unreadable input. what() is one line naming the file and where:
// "door.ply: line 12: ..." or "door.ply: byte 4096: ...".
class IngestError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace dentmark::ingest
