#pragma once
// Pictures for people: the report PNG (the deviation from the reference surface as a
// colour map with a scale bar, each defect ringed and numbered, design features by their
// outline, a legend, a table of the defects and a title line; report_layout.h says where
// each goes), and the mesh with defect triangles coloured (PLY, for MeshLab or
// CloudCompare).

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "dentmark/common/ingest/mesh.h"
#include "dentmark/host/detect/detector.h"
#include "dentmark/host/report/report_layout.h"

namespace cv {
class Mat;
}

namespace dentmark::report {

// Throws ReportError on failure; nothing is left half-written.
void write_report_png(const std::string& path, const detect::Detection& detection, const ReportInfo& info);
// The report as an 8-bit BGR image, drawn as `layout` places it.
cv::Mat render_report(const detect::Detection& detection, const ReportLayout& layout);
void write_marked_ply(const std::string& path, const ingest::MeshView& mesh,
                      const detect::Detection& detection);
// The marked PLY's colour per vertex: red on a dent's triangles, blue on a bump's, yellow
// on a design feature's, grey elsewhere (through every chart's map, charts.h).
std::vector<std::array<std::uint8_t, 3>> marked_vertex_colours(const ingest::MeshView& mesh,
                                                               const detect::Detection& detection);

}  // namespace dentmark::report
