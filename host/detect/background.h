#pragma once
// Background in the scan: a wall, the floor or a rack seen around the panel. A scanner
// whose field of view is larger than the panel records what lies behind it as well.
// Projected on the height map it surrounds the panel a step of tens of centimetres
// behind it and shows through every pixel the panel leaves empty; the reference surface
// cannot follow that, and defects were lost (5 of 8 on a panel 0.6 m before a wall).
//
// So the surface is split into pieces in space first: cells of ~16 mm holding leaves,
// joined to the 26 around them. The panel is the piece nearest the sensor among the
// large ones. A large piece that lies far off the panel's shape (the quadratic through
// it over the map plane) is background; a piece on that shape (the panel beyond a
// dropout across it) stays, and so does anything small (the inner panel seen through a
// hole, an outlier).

#include <cstdint>
#include <vector>

#include "dentmark/host/detect/height_map.h"
#include "dentmark/host/detect/linear_octree.h"
#include "stray_points.h"

namespace dentmark::detect {

struct Background {
  std::vector<std::uint8_t> leaf;  // per leaf: 1 if background (empty: there is none)
  double area = 0.0;               // the background leaves' surface area (m²)
};

// The background among the leaves with surface inside `box`; `frame` holds the map's
// origin and axes (w towards the sensor).
Background find_background(const LinearOctree& tree, const HeightMap& frame, const Box& box);

// The spacing of the samples (ingest::point_spacing) over the triangles off the
// background only: a wall seen 0.6 m behind a panel holds as many samples as the panel,
// spaced 1.8 times as wide. 0 when no sampled triangle is left.
double panel_spacing(const ingest::MeshView& mesh, const LinearOctree& tree,
                     const std::vector<std::uint8_t>& background_leaf);

}  // namespace dentmark::detect
