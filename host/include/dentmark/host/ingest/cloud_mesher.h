#pragma once
// Meshes a point cloud in the sensor's view (2.5D): a structured-light sensor sees the
// surface as a height field over its image, so neighbours in the image are neighbours
// on the surface. An organised cloud (points in the camera's raster order, missing ones
// left out or NaN) is stitched row to row, every point kept at any density; any other
// order by the Delaunay triangulation of the points in the image (delaunay_mesher.h).

#include <Eigen/Core>
#include <vector>

#include "dentmark/common/ingest/mesh.h"

namespace dentmark::ingest {

// Builds triangles over 'mesh.vertices' (mesh.triangles is replaced). The view is the
// perspective from the frame origin when every point lies in front of it (z > 0, the
// 'sls' convention), otherwise an orthographic view along the cloud's least-variance axis.
// Triangles whose longest edge exceeds 4x the point spacing (depth jumps) are not made.
void mesh_point_cloud(Mesh& mesh);

}  // namespace dentmark::ingest
