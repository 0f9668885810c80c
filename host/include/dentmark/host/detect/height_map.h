#pragma once
// The scan seen as a height field: octree leaves projected onto the panel's mean plane
// (axes u, v; w towards the sensor), one pixel per finest node. A single-view SLS scan
// is a height field over its image, and so over a plane near its view direction.

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "dentmark/host/detect/linear_octree.h"

namespace dentmark::detect {

struct HeightMap {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();    // scan frame, m
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();  // rows u, v, w in scan frame
  double pixel = 0.001;                                // m
  int cols = 0, rows = 0;
  double u0 = 0.0, v0 = 0.0;    // map coordinates of pixel (0, 0)'s corner
  std::vector<float> weight;    // Σ a / pixel² (0: no surface)
  std::vector<float> u, v, w;   // area-weighted mean point in map coordinates (m)
  std::vector<float> cos_tilt;  // |mean normal · w|: converts w offsets to normal offsets
  // Leaves more than 'layer_depth' behind their column's front, kept out of the map:
  // seen through a hole, or outliers (map coordinates, m).
  std::vector<Eigen::Vector3f> behind;
  // The sensor in map coordinates, when the scan frame's origin is the sensor (w > 0.1 m).
  bool has_viewpoint = false;
  // Surface left out as background: a wall or floor far behind the panel (m², see
  // host/detect/background.h).
  double background_area = 0.0;
  Eigen::Vector3d viewpoint = Eigen::Vector3d::Zero();

  std::size_t size() const { return static_cast<std::size_t>(cols) * static_cast<std::size_t>(rows); }
  Eigen::Vector3d to_scan(double pu, double pv, double pw) const {
    return origin + axes.transpose() * Eigen::Vector3d(pu, pv, pw);
  }
  Eigen::Vector3d to_map(const Eigen::Vector3d& p) const { return axes * (p - origin); }
  // Row and column of the pixel holding map point (pu, pv); false outside.
  // (Times the pixel's inverse, which a loop computes once: two divisions a point made
  // the map's per-leaf pixel pass divider-bound.)
  bool cell_of(double pu, double pv, int& row, int& col) const {
    const double inv = 1.0 / pixel;
    const double c = (pu - u0) * inv, r = (pv - v0) * inv;
    if (!(c >= 0.0 && r >= 0.0 && c < cols && r < rows)) return false;  // (NaN: outside)
    row = static_cast<int>(r), col = static_cast<int>(c);               // (as floor: both >= 0)
    return true;
  }
  // Pixel holding map point (pu, pv), or -1 outside.
  long pixel_of(double pu, double pv) const {
    int r = 0, c = 0;
    return cell_of(pu, pv, r, c) ? static_cast<long>(r) * cols + c : -1;
  }
};

// Projects the leaves. 'w' points to the frame origin's side (the sensor's) of the plane,
// or, where the origin lies within 10 cm of it (no sensor's: a profiler's or a part's
// frame), to the side the triangles face.
// A single view sees only the front surface of each column: leaves more than layer_depth
// behind the column's front go to 'behind' instead of being averaged into the pixel.
// background_leaf, when given, receives per leaf 1 for background (background.h), or
// nothing when there is none.
// chart_w: zero for the whole scan's map. Else the map is a chart's (charts.h): w on
// chart_w's side (the chart's axis, turned as the whole scan's map would look); and as a
// chart lies at up to 55° to the octree's grid, single pixels the grid's steps left empty
// between surface pixels are filled from their neighbours.
HeightMap build_height_map(const LinearOctree& tree, double pixel, double layer_depth,
                           std::vector<std::uint8_t>* background_leaf = nullptr,
                           const Eigen::Vector3d& chart_w = Eigen::Vector3d::Zero());

}  // namespace dentmark::detect
