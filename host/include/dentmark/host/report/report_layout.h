#pragma once
// Where everything on the report PNG goes (write_report_png draws it): a title line, the
// deviation map of each chart with a scale bar in mm, each defect ringed and numbered,
// and beside the maps a colour bar, a legend for every kind of mark and a table of the
// defects (id, class, diameter, depth, position). Kept apart from the drawing so that a
// test can check that every mark, label and row lies inside the image.

#include <string>
#include <vector>

#include "dentmark/host/detect/detector.h"

namespace dentmark::report {

// What the report says of the scan besides the detection.
struct ReportInfo {
  std::string file;  // the scan file as the user named it
  std::string date;  // when it was scanned, as printed ("2026-12-06 02:30 UTC")
};

// Pixel rectangle, canvas coordinates (x right, y down), [x, x + w) x [y, y + h).
struct Box {
  int x = 0, y = 0, w = 0, h = 0;
  int right() const { return x + w; }
  int bottom() const { return y + h; }
  bool inside(const Box& outer) const {
    return x >= outer.x && y >= outer.y && right() <= outer.right() && bottom() <= outer.bottom();
  }
  bool overlaps(const Box& o) const {
    return x < o.right() && o.x < right() && y < o.bottom() && o.y < bottom();
  }
};

// Text at a box: `box` holds the whole text (ascent and descent); drawn from `baseline`.
struct TextItem {
  std::string text;
  Box box;
  int baseline = 0;
  double scale = 0.5;  // OpenCV Hershey simplex font scale
  int thickness = 1;
};

struct PanelLayout {
  Box map;             // where the panel's deviation image goes
  double scale = 1.0;  // canvas pixels per map pixel
  std::string title;   // "chart 2 of 3 ..." when the surface was seen in charts; else empty
  TextItem title_text;
};

struct DefectMark {
  std::size_t defect = 0;  // index into Detection::defects
  std::size_t panel = 0;   // the panel it is drawn on
  // Drawn on a chart that shows the defect's surface but does not own it (charts
  // overlap): a thin grey ring and number, so that the blob there is not taken for a
  // defect missed.
  bool echo = false;
  int cx = 0, cy = 0;  // ring centre, canvas pixels
  int radius = 0;      // ring radius: the measured diameter's half, at least a few pixels
  TextItem label;      // its number, in a box beside the ring, inside the panel
};

struct LegendEntry {
  enum class Symbol { kDefectRing, kDefectEcho, kFeatureOutline, kNoSurface } symbol;
  Box swatch;
  TextItem text;
};

struct ReportLayout {
  int width = 0, height = 0;
  std::vector<TextItem> title;  // file and date; counts, spacing, noise
  std::vector<PanelLayout> panels;
  std::vector<DefectMark> marks;  // each defect's on its own chart, in order; then echoes
  Box scale_bar;                  // a bar `scale_bar_mm` long at the first panel's scale
  double scale_bar_mm = 0.0;
  TextItem scale_bar_text;
  Box colour_bar;      // the deviation colour scale, +range at the top
  double range = 0.0;  // m: the colour map spans -range .. +range
  std::vector<TextItem> colour_ticks;
  TextItem colour_title;
  std::vector<LegendEntry> legend;
  TextItem table_title;
  std::vector<std::vector<TextItem>> table;  // header row, then a row per defect shown
  TextItem table_more;                       // "... N more in the JSON" when not all fit; else empty
};

// The maps to draw: the scan's, then the other charts'.
struct PanelMap {
  const detect::HeightMap& map;
  const std::vector<float>& deviation;
  const std::vector<std::int32_t>& labels;
};
std::vector<PanelMap> panel_maps(const detect::Detection& detection);

// Which panel each defect is drawn on: the chart whose labels hold it, else the first.
std::vector<std::size_t> defect_panels(const detect::Detection& detection);

ReportLayout layout_report(const detect::Detection& detection, const ReportInfo& info);

}  // namespace dentmark::report
