#include "dentmark/host/report/report_layout.h"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "dentmark/host/report/defects_json.h"

namespace dentmark::report {

namespace {

constexpr int kMargin = 24;           // px round the canvas and between blocks
constexpr double kMapWidth = 1150.0;  // px the maps are scaled to (at most)
constexpr double kMapHeight = 1500.0;
constexpr int kSideMinWidth = 400;  // the colour bar, legend and table column
constexpr std::size_t kTableRows = 60;
// Font scales (OpenCV Hershey simplex): at ~1800 px across A4 landscape, 0.6 prints with
// capitals about 2 mm high.
constexpr double kSmall = 0.6, kMedium = 0.65;

TextItem text_at(std::string text, int x, int top, double scale, int thickness = 1) {
  int base = 0;
  const cv::Size s = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, scale, thickness, &base);
  TextItem t;
  t.text = std::move(text);
  t.scale = scale;
  t.thickness = thickness;
  t.box = {x, top, s.width + thickness, s.height + base + thickness};
  t.baseline = top + s.height;
  return t;
}

__attribute__((format(printf, 1, 2))) std::string format(const char* fmt, ...) {
  char b[64];
  va_list args;
  va_start(args, fmt);
  std::vsnprintf(b, sizeof b, fmt, args);
  va_end(args);
  return b;
}

// The class as the report's table and legend name it: class_name, with "feature" for a
// design feature (the column is narrow).
const char* class_word(protocol::DefectClass c) {
  return c == protocol::DefectClass::kDesignFeature ? "feature" : class_name(c);
}

std::vector<TextItem> title_lines(const detect::Detection& det, const ReportInfo& info, double range) {
  std::size_t dents = 0, bumps = 0, holes = 0, features = 0;
  for (const auto& f : det.defects) {
    dents += f.defect.defect_class == protocol::DefectClass::kDent;
    bumps += f.defect.defect_class == protocol::DefectClass::kBump;
    holes += f.defect.defect_class == protocol::DefectClass::kHole;
  }
  for (const auto& f : det.features)
    features += f.defect.defect_class == protocol::DefectClass::kDesignFeature;
  std::vector<TextItem> lines;
  lines.push_back(
      text_at(info.file + (info.date.empty() ? "" : "   scanned " + info.date), kMargin, kMargin, 0.75, 2));
  const std::string counts = std::to_string(det.defects.size()) + " defects (" + std::to_string(dents) +
                             " dents, " + std::to_string(bumps) + " bumps, " + std::to_string(holes) +
                             " holes), " + std::to_string(features) + " design features";
  const std::string figures = "point spacing " + format("%.2f mm", 1e3 * det.stats.spacing) +
                              ",  deviation noise " + format("%.3f mm", 1e3 * det.stats.deviation_noise) +
                              " (1 sigma),  colours " + format("%.2f", -1e3 * range) +
                              format(" to +%.2f mm", 1e3 * range);
  lines.push_back(text_at(counts, kMargin, lines.back().box.bottom() + 10, kMedium));
  lines.push_back(text_at(figures, kMargin, lines.back().box.bottom() + 6, kMedium));
  return lines;
}

// The longest round length (mm) no longer than `max_px` at `px_per_mm`.
double scale_bar_length(double px_per_mm, double max_px) {
  double best = 1.0;
  for (double mm : {1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0, 2000.0})
    if (mm * px_per_mm <= max_px) best = mm;
  return best;
}

// Defect k's mark on panel p: a ring of its diameter (at least 7 px) and its number
// beside, on the first side that stays inside the panel clear of the numbers `taken`.
// An echo (a chart that does not own the defect) only where that chart has surface
// within 5 mm of the defect's centre; nullopt elsewhere.
std::optional<DefectMark> place_mark(const detect::Detection& det, std::size_t k,
                                     const std::vector<PanelMap>& maps, const ReportLayout& L, std::size_t p,
                                     bool echo, std::vector<Box>& taken) {
  const auto& d = det.defects[k].defect;
  const PanelLayout& panel = L.panels[p];
  const auto& map = maps[p].map;
  const Eigen::Vector3d q = map.to_map(d.position);
  if (echo) {
    const long px = map.pixel_of(q.x(), q.y());
    if (px < 0 || !std::isfinite(maps[p].deviation[static_cast<std::size_t>(px)]) ||
        map.w.size() != map.size() || !(std::abs(map.w[static_cast<std::size_t>(px)] - q.z()) < 0.005))
      return std::nullopt;
  }
  DefectMark m;
  m.defect = k;
  m.panel = p;
  m.echo = echo;
  m.cx = std::clamp(panel.map.x + static_cast<int>(std::lround((q.x() - map.u0) / map.pixel * panel.scale)),
                    panel.map.x, panel.map.right() - 1);
  m.cy = std::clamp(panel.map.y + static_cast<int>(std::lround((q.y() - map.v0) / map.pixel * panel.scale)),
                    panel.map.y, panel.map.bottom() - 1);
  m.radius = std::max(7, static_cast<int>(std::lround(0.5 * d.diameter / map.pixel * panel.scale)) + 3);
  // Never past the canvas: a ring at the edge of a map stays within the margin.
  m.radius = std::min({m.radius, m.cx - 2, m.cy - 2, L.width - 3 - m.cx, L.height - 3 - m.cy});
  TextItem label = text_at(std::to_string(d.id), 0, 0, kMedium, 1);
  label.box.w += 8, label.box.h += 4;  // padding of its box
  const int w = label.box.w, h = label.box.h, off = static_cast<int>(std::lround(m.radius * 0.71)) + 2;
  const std::vector<std::pair<int, int>> tries{{m.cx + off, m.cy - off - h},
                                               {m.cx - off - w, m.cy - off - h},
                                               {m.cx + off, m.cy + off},
                                               {m.cx - off - w, m.cy + off},
                                               {m.cx + m.radius + 3, m.cy - h / 2},
                                               {m.cx - m.radius - 3 - w, m.cy - h / 2}};
  Box chosen{-1, -1, w, h};
  for (const bool avoid : {true, false}) {
    for (const auto& [tx, ty] : tries) {
      const Box b{tx, ty, w, h};
      if (!b.inside(panel.map)) continue;
      if (avoid && std::any_of(taken.begin(), taken.end(), [&](const Box& o) { return o.overlaps(b); }))
        continue;
      chosen = b;
      break;
    }
    if (chosen.x >= 0) break;
  }
  if (chosen.x < 0)  // a panel smaller than the label: kept on the canvas
    chosen = {std::clamp(tries[0].first, 0, L.width - w), std::clamp(tries[0].second, 0, L.height - h), w, h};
  // The text sits 4 px in from its box's left edge and 2 px down (write_report_png).
  label.baseline = chosen.y + 2 + label.baseline;
  label.box = chosen;
  taken.push_back(chosen);
  m.label = std::move(label);
  return m;
}

}  // namespace

std::vector<PanelMap> panel_maps(const detect::Detection& det) {
  std::vector<PanelMap> panels{{det.map, det.deviation, det.labels}};
  for (const auto& c : det.more_charts) panels.push_back({c.map, c.deviation, c.labels});
  return panels;
}

std::vector<std::size_t> defect_panels(const detect::Detection& det) {
  const std::vector<PanelMap> panels = panel_maps(det);
  std::vector<std::size_t> where(det.defects.size(), 0);
  if (panels.size() == 1) return where;
  std::vector<bool> seen(det.defects.size(), false);
  for (std::size_t p = 0; p < panels.size(); ++p)
    for (const std::int32_t l : panels[p].labels)
      if (l >= 0 && !seen[static_cast<std::size_t>(l)])
        seen[static_cast<std::size_t>(l)] = true, where[l] = p;
  return where;
}

namespace {

// --- The stages of layout_report, top to bottom and left to right ---

// The maps, one under the other (a title over each when the surface wraps round into
// several charts), at one scale (canvas px per metre) for all, so that one scale bar
// under them serves all. Fills L.panels and the scale bar; returns the bottom of the
// left column.
int layout_maps(ReportLayout& L, const std::vector<PanelMap>& maps, int top) {
  double px_per_m = 1e9, total_h = 0.0;
  for (const PanelMap& m : maps) {
    px_per_m = std::min(px_per_m, kMapWidth / (m.map.cols * m.map.pixel));
    total_h += m.map.rows * m.map.pixel;
  }
  px_per_m = std::min(px_per_m, kMapHeight / total_h);
  int y = top, maps_w = 0;
  for (std::size_t p = 0; p < maps.size(); ++p) {
    PanelLayout panel;
    if (maps.size() > 1) {
      panel.title = "chart " + std::to_string(p + 1) + " of " + std::to_string(maps.size()) +
                    " (the surface wraps round: each chart seen face-on)";
      panel.title_text = text_at(panel.title, kMargin, y, kMedium);
      y = panel.title_text.box.bottom() + 6;
    }
    panel.scale = px_per_m * maps[p].map.pixel;
    panel.map = {kMargin, y, std::max(1, static_cast<int>(std::lround(maps[p].map.cols * panel.scale))),
                 std::max(1, static_cast<int>(std::lround(maps[p].map.rows * panel.scale)))};
    maps_w = std::max(maps_w, panel.map.w);
    y = panel.map.bottom() + 12;
    L.panels.push_back(std::move(panel));
  }
  L.scale_bar_mm = scale_bar_length(px_per_m * 1e-3, 0.4 * maps_w);
  L.scale_bar = {kMargin, y + 6, static_cast<int>(std::lround(L.scale_bar_mm * px_per_m * 1e-3)), 8};
  L.scale_bar_text = text_at(format("%.0f mm", L.scale_bar_mm), L.scale_bar.right() + 10, y, kMedium);
  return std::max(L.scale_bar.bottom(), L.scale_bar_text.box.bottom());
}

// The side column's left edge: clear of the maps, their titles and the scale bar.
int side_column_x(const ReportLayout& L) {
  int maps_w = 0;
  for (const auto& panel : L.panels) maps_w = std::max(maps_w, panel.map.w);
  int left_right = std::max(kMargin + maps_w, L.scale_bar_text.box.right());
  for (const auto& panel : L.panels) left_right = std::max(left_right, panel.title_text.box.right());
  return left_right + 2 * kMargin;
}

// The colour bar at (sx, top) with its title and five ticks over ±L.range; returns the
// y under it.
int layout_colour_bar(ReportLayout& L, int sx, int top) {
  L.colour_title = text_at("deviation from the reference surface", sx, top, kMedium);
  L.colour_bar = {sx, L.colour_title.box.bottom() + 12, 24, 200};
  for (int t = 2; t >= -2; --t) {
    const int yt = L.colour_bar.y + (L.colour_bar.h - 1) * (2 - t) / 4;
    std::string label = format("%+.2f mm", 1e3 * L.range * t / 2.0);
    if (t == 2) label += " (up: bump)";
    if (t == -2) label += " (down: dent)";
    TextItem item = text_at(label, L.colour_bar.right() + 12, 0, kSmall);
    const int dy = yt - (item.box.h - 2) / 2 - item.box.y;  // centred on its tick
    item.box.y += dy, item.baseline += dy;
    L.colour_ticks.push_back(item);
  }
  return std::max(L.colour_bar.bottom(), L.colour_ticks.back().box.bottom()) + kMargin;
}

// The legend from (sx, sy), one swatch and its text a line (the echo only with several
// charts); returns the y under it.
int layout_legend(ReportLayout& L, int sx, int sy, bool charts) {
  const auto legend = [&](LegendEntry::Symbol symbol, const std::string& text) {
    LegendEntry e{symbol, {sx, sy, 44, 28}, text_at(text, sx + 56, sy, kSmall)};
    const int dy = e.swatch.y + e.swatch.h / 2 - (e.text.box.y + e.text.box.h / 2);
    e.text.box.y += dy, e.text.baseline += dy;
    sy = std::max(e.swatch.bottom(), e.text.box.bottom()) + 8;
    L.legend.push_back(std::move(e));
  };
  legend(LegendEntry::Symbol::kDefectRing, "defect: ring of its diameter, number as in the table");
  if (charts) legend(LegendEntry::Symbol::kDefectEcho, "the same defect seen on another chart (grey)");
  legend(LegendEntry::Symbol::kFeatureOutline, "design feature (line, handle, edge): its outline");
  legend(LegendEntry::Symbol::kNoSurface, "no surface measured");
  return sy + kMargin / 2;
}

// The defect table from (sx, sy): the first kTableRows defects, numbers right-aligned in
// their columns, words left-aligned, and a line for the rest; returns the y under it.
int layout_table(ReportLayout& L, const detect::Detection& det, int sx, int sy) {
  L.table_title = text_at("defects (position in the scan's frame)", sx, sy, kMedium);
  sy = L.table_title.box.bottom() + 10;
  const std::vector<std::string> head{"#", "class", "diam. mm", "depth mm", "x mm", "y mm", "z mm"};
  std::vector<std::vector<std::string>> cells{head};
  const std::size_t shown = std::min(det.defects.size(), kTableRows);
  for (std::size_t k = 0; k < shown; ++k) {
    const auto& d = det.defects[k].defect;
    cells.push_back({std::to_string(d.id), class_word(d.defect_class), format("%.1f", 1e3 * d.diameter),
                     format("%.2f", 1e3 * std::abs(d.height)), format("%.1f", 1e3 * d.position.x()),
                     format("%.1f", 1e3 * d.position.y()), format("%.1f", 1e3 * d.position.z())});
  }
  std::vector<int> col_w(head.size(), 0);
  for (const auto& row : cells)
    for (std::size_t c = 0; c < row.size(); ++c)
      col_w[c] = std::max(col_w[c], text_at(row[c], 0, 0, kSmall).box.w);
  for (const auto& row : cells) {
    std::vector<TextItem> items;
    int x = sx, h = 0;
    for (std::size_t c = 0; c < row.size(); ++c) {
      TextItem t = text_at(row[c], x, sy, kSmall);
      if (c >= 2) t.box.x += col_w[c] - t.box.w;
      items.push_back(t);
      x += col_w[c] + 18;
      h = std::max(h, t.box.h);
    }
    L.table.push_back(std::move(items));
    sy += h + 8;
  }
  if (shown < det.defects.size()) {
    L.table_more =
        text_at("... and " + std::to_string(det.defects.size() - shown) + " more in the JSON defect list", sx,
                sy, kSmall);
    sy = L.table_more.box.bottom() + 8;
  }
  return sy;
}

// The canvas: wide enough for every text of the side column and the title, tall enough
// for both columns.
void size_canvas(ReportLayout& L, int sx, int left_bottom, int side_bottom) {
  int right = sx + kSideMinWidth;
  for (const auto& row : L.table) right = std::max(right, row.back().box.right());
  for (const auto& e : L.legend) right = std::max(right, e.text.box.right());
  for (const auto& t : L.colour_ticks) right = std::max(right, t.box.right());
  for (const auto& t : L.title) right = std::max(right, t.box.right());
  L.width = right + kMargin;
  L.height = std::max(left_bottom, side_bottom) + kMargin;
}

// Defect marks: on the chart that owns each defect, and on any other chart that shows
// the same surface there (charts overlap), an echo; labels placed clear of each other.
void layout_marks(ReportLayout& L, const detect::Detection& det, const std::vector<PanelMap>& maps) {
  const std::vector<std::size_t> where = defect_panels(det);
  std::vector<Box> taken;
  for (std::size_t k = 0; k < det.defects.size(); ++k)
    if (auto m = place_mark(det, k, maps, L, where[k], false, taken)) L.marks.push_back(std::move(*m));
  for (std::size_t p = 0; p < maps.size() && maps.size() > 1; ++p)
    for (std::size_t k = 0; k < det.defects.size(); ++k)
      if (p != where[k])
        if (auto m = place_mark(det, k, maps, L, p, true, taken)) L.marks.push_back(std::move(*m));
}

}  // namespace

ReportLayout layout_report(const detect::Detection& det, const ReportInfo& info) {
  ReportLayout L;
  // Colour range: the larger of 0.1 mm and 8x the measured deviation noise.
  L.range = std::max(1e-4, 8.0 * det.stats.deviation_noise);
  L.title = title_lines(det, info, L.range);
  const int top = L.title.back().box.bottom() + kMargin;
  const std::vector<PanelMap> maps = panel_maps(det);
  const int left_bottom = layout_maps(L, maps, top);
  const int sx = side_column_x(L);
  int sy = layout_colour_bar(L, sx, top);
  sy = layout_legend(L, sx, sy, maps.size() > 1);
  sy = layout_table(L, det, sx, sy);
  size_canvas(L, sx, left_bottom, sy);
  layout_marks(L, det, maps);
  return L;
}

}  // namespace dentmark::report
