#pragma once
// Pictures for people: the deviation from the reference surface as a colour map with
// each defect ringed and labelled and a legend in mm (PNG), and the mesh with defect
// triangles coloured (PLY, for MeshLab or CloudCompare).

#include <string>

#include "dentmark/host/detect/detector.h"
#include "dentmark/host/ingest/mesh.h"

namespace dentmark::report {

// Throws ReportError on failure; nothing is left half-written.
void write_report_png(const std::string& path, const detect::Detection& detection);
void write_marked_ply(const std::string& path, const ingest::MeshView& mesh,
                      const detect::Detection& detection);

}  // namespace dentmark::report
