#pragma once
// Which length unit a scan file is in, when the user does not say: the files carry no
// unit, scanners write metres or millimetres, and a millimetre scan read as metres
// silently finds nothing (its "spacing" is 0.5 m).

#include <cstddef>
#include <functional>

#include "dentmark/common/ingest/mesh_view.h"

namespace dentmark::ingest {

// Measured on a sample of the scan, in the file's units.
struct ScaleEvidence {
  double extent = 0.0;   // diagonal of the box holding the middle 96 % of the vertices per axis
  double spacing = 0.0;  // median shortest triangle edge
};

ScaleEvidence measure_scale(const MeshView& mesh);

// The scan's point spacing: the median shortest edge of ~50 000 sampled triangles (on
// grid meshes the other edges are diagonals); 0 without triangles. use(t), when given,
// picks the sampled triangles t that count.
double point_spacing(const MeshView& mesh, const std::function<bool(std::size_t)>& use = {});

// Whether a scan read as metres is in millimetres: no body panel is over 20 m across or
// sampled over 5 cm apart, and no millimetre scan of one is under 20 mm across with
// samples under 0.05 mm apart.
bool looks_like_millimetres(const ScaleEvidence& e);

}  // namespace dentmark::ingest
