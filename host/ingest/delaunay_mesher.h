#pragma once
// An unorganised point cloud meshed by the Delaunay triangulation of its points in the
// sensor's image (CGAL). Every point is kept whatever the density: a panel at 55 degrees
// to the view is twice as dense at its far end as at its near one, which no grid of one
// cell size fits (one point per cell lost a fifth of the points at the dense end and
// left holes at the sparse end).

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "dentmark/common/ingest/mesh.h"

namespace dentmark::ingest {

// Appends to mesh.triangles the Delaunay triangles over the points 'valid' (indices into
// mesh.vertices) at image positions img[i], leaving out those with a 3D edge longer than
// 4 times the median edge (depth jumps, openings) or a circumradius over 3 (the convex
// hull's slivers).
void mesh_delaunay(Mesh& mesh, const std::vector<Eigen::Vector2d>& img,
                   const std::vector<std::uint32_t>& valid);

}  // namespace dentmark::ingest
