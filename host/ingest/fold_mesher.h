#pragma once
// An unorganised cloud whose surface turns past the sensor's line of sight (views merged
// round a fender, a bumper's corner, a tube) is no height field over the sensor's image:
// its far sides fold over the near ones there. Such a cloud is meshed in charts, each
// the Delaunay triangulation of a connected part of the surface in its own plane.

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "dentmark/common/ingest/mesh.h"

namespace dentmark::ingest {

// The direction from a point towards the viewer: the sensor at the origin of the
// cloud's frame (perspective) or along a fixed axis (orthographic).
struct ViewDirection {
  bool perspective = true;
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // towards the viewer when orthographic

  Eigen::Vector3d towards_viewer(const Eigen::Vector3d& p) const {
    return perspective ? Eigen::Vector3d(-p.normalized()) : axis;
  }
};

// When more than 1 % of the surface (points 'valid', indices into mesh.vertices) is seen
// edge-on or folds over (its normal over 80 degrees from the line of sight), appends
// triangles meshing it in charts, each facing the way its neighbours do, and returns
// the number of charts. Otherwise leaves the mesh alone and returns 0.
std::size_t mesh_folded_cloud(Mesh& mesh, const std::vector<std::uint32_t>& valid, const ViewDirection& view);

}  // namespace dentmark::ingest
