#pragma once
// Stray points far off the panel. An outlier vertex hundreds of metres away, meshed to
// its neighbours or not, stretches the scan's bounding box: the octree would need more
// than its 16 levels for the finest node size, and the scan could not be inspected at
// all. Such a scan is cropped to the panel first.

#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "dentmark/common/ingest/mesh.h"
#include "dentmark/common/ingest/mesh_view.h"

namespace dentmark::detect {

struct Box {
  Eigen::Vector3f lo, hi;
};

// The vertices' bounding box (the view's own when it has one).
Box bounding_box(const ingest::MeshView& mesh);

// The box that holds the panel, from sampled points (x, y, z per axis; reordered): per
// axis their middle 98 %, widened by a quarter of the box's largest side each way
// (across a panel seen face-on the box is thin, and a handle stands proud of it).
// Unbounded when fewer than 100 points are given: too few to tell a stray one.
Box middle_box(std::vector<float> (&samples)[3]);

// The box that holds the panel: per axis, the middle 98 % of the vertices (sampled),
// widened by a quarter of its largest side each way. Every vertex of a real scan is
// inside.
Box panel_box(const ingest::MeshView& mesh);

// The mesh without the triangles that reach outside 'box' (and the vertices no kept
// triangle uses), renumbered; 'dropped' counts the triangles left out.
ingest::Mesh crop(const ingest::MeshView& mesh, const Box& box, std::size_t& dropped);

}  // namespace dentmark::detect
