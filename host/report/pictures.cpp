#include "dentmark/host/report/pictures.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/imgproc.hpp>

#include "dentmark/common/atomic_file.h"
#include "dentmark/common/image/png_io.h"
#include "dentmark/common/ingest/mesh_writer.h"
#include "dentmark/host/report/defects_json.h"

namespace dentmark::report {

namespace {

const cv::Scalar kBlack(0, 0, 0), kWhite(255, 255, 255), kNoSurfaceBorder(170, 170, 170);
// Design features' outlines: a thin dark line, half transparent, so that it stays in the
// background of the map and is seen on every colour and on no-surface white.
const cv::Scalar kOutline(0, 0, 0);
constexpr double kOutlineOpacity = 0.5;

cv::Rect rect(const Box& b) {
  return {b.x, b.y, b.w, b.h};
}

void draw_text(cv::Mat& canvas, const TextItem& t, int x_pad = 0, const cv::Scalar& colour = kBlack) {
  if (t.text.empty()) return;
  cv::putText(canvas, t.text, {t.box.x + x_pad, t.baseline}, cv::FONT_HERSHEY_SIMPLEX, t.scale, colour,
              t.thickness, cv::LINE_AA);
}

// The JET colour of a deviation `d` on the colour map spanning -range .. +range.
cv::Vec3b jet(double d, double range) {
  cv::Mat px(1, 1, CV_8U, cv::Scalar(std::clamp(128.0 + 127.0 * d / range, 0.0, 255.0))), c;
  cv::applyColorMap(px, c, cv::COLORMAP_JET);
  return c.at<cv::Vec3b>(0, 0);
}

// A pixel without surface amid surface (5 or more of its 8 neighbours have some: a
// sample that fell between pixels) shown as their mean; a real gap stays empty.
float shown_deviation(const PanelMap& panel, int r, int c) {
  const auto& map = panel.map;
  const auto at = [&](int rr, int cc) {
    return panel.deviation[static_cast<std::size_t>(rr) * map.cols + cc];
  };
  const float d = at(r, c);
  if (std::isfinite(d)) return d;
  float sum = 0.0f;
  int n = 0;
  for (int dr = -1; dr <= 1; ++dr)
    for (int dc = -1; dc <= 1; ++dc) {
      const int rr = r + dr, cc = c + dc;
      if ((dr == 0 && dc == 0) || rr < 0 || cc < 0 || rr >= map.rows || cc >= map.cols) continue;
      if (const float v = at(rr, cc); std::isfinite(v)) sum += v, ++n;
    }
  return n >= 5 ? sum / static_cast<float>(n) : d;
}

// The panel's deviation as colours at the layout's size; white where no surface is.
cv::Mat deviation_image(const PanelMap& panel, double range, const Box& size) {
  const auto& map = panel.map;
  cv::Mat grey(map.rows, map.cols, CV_8U), empty(map.rows, map.cols, CV_8U, cv::Scalar(0));
  for (int r = 0; r < map.rows; ++r)
    for (int c = 0; c < map.cols; ++c) {
      const float d = shown_deviation(panel, r, c);
      if (!std::isfinite(d)) {
        empty.at<std::uint8_t>(r, c) = 255;
        grey.at<std::uint8_t>(r, c) = 128;
        continue;
      }
      grey.at<std::uint8_t>(r, c) =
          static_cast<std::uint8_t>(std::clamp(128.0 + 127.0 * d / range, 0.0, 255.0));
    }
  cv::Mat colour;
  cv::applyColorMap(grey, colour, cv::COLORMAP_JET);
  colour.setTo(kWhite, empty);
  cv::Mat big;
  const bool up = size.w >= map.cols;
  cv::resize(colour, big, {size.w, size.h}, 0, 0, up ? cv::INTER_NEAREST : cv::INTER_AREA);
  return big;
}

// The outline of every design feature's pixels on the panel, drawn lightly over `image`.
void draw_feature_outlines(cv::Mat& image, const PanelMap& panel, const detect::Detection& det,
                           double scale) {
  const auto& map = panel.map;
  cv::Mat mask(map.rows, map.cols, CV_8U, cv::Scalar(0));
  for (int r = 0; r < map.rows; ++r)
    for (int c = 0; c < map.cols; ++c) {
      const std::int32_t l = panel.labels[static_cast<std::size_t>(r) * map.cols + c];
      if (detect::is_feature_label(l) &&
          det.features[detect::feature_index(l)].defect.defect_class == protocol::DefectClass::kDesignFeature)
        mask.at<std::uint8_t>(r, c) = 255;
    }
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(mask, contours, cv::RETR_LIST, cv::CHAIN_APPROX_SIMPLE);
  for (auto& contour : contours)
    for (auto& p : contour)  // pixel centres at the image's scale
      p = {static_cast<int>(std::lround((p.x + 0.5) * scale)),
           static_cast<int>(std::lround((p.y + 0.5) * scale))};
  cv::Mat overlay = image.clone();
  cv::polylines(overlay, contours, true, kOutline, 1, cv::LINE_AA);
  cv::addWeighted(overlay, kOutlineOpacity, image, 1.0 - kOutlineOpacity, 0.0, image);
}

// A defect's own ring is black on a white halo; an echo's thin grey.
const cv::Scalar kEcho(110, 110, 110);

void draw_ring(cv::Mat& canvas, cv::Point c, int radius, bool echo) {
  if (echo) {
    cv::circle(canvas, c, radius, kEcho, 1, cv::LINE_AA);
    return;
  }
  cv::circle(canvas, c, radius, kWhite, 4, cv::LINE_AA);  // a halo: visible on every colour
  cv::circle(canvas, c, radius, kBlack, 2, cv::LINE_AA);
}

void draw_number(cv::Mat& canvas, const TextItem& label, bool echo) {
  cv::rectangle(canvas, rect(label.box), kWhite, cv::FILLED);
  cv::rectangle(canvas, rect(label.box), echo ? kEcho : kBlack, 1);
  draw_text(canvas, label, 4, echo ? kEcho : kBlack);
}

void draw_legend(cv::Mat& canvas, const LegendEntry& e) {
  const cv::Point mid(e.swatch.x + e.swatch.w / 2, e.swatch.y + e.swatch.h / 2);
  cv::Mat swatch = canvas(rect(e.swatch));
  switch (e.symbol) {
    case LegendEntry::Symbol::kDefectRing:
      swatch.setTo(cv::Scalar(jet(-0.6, 1.0)));
      draw_ring(canvas, mid, e.swatch.h / 2 - 3, false);
      break;
    case LegendEntry::Symbol::kDefectEcho:
      swatch.setTo(cv::Scalar(jet(0.0, 1.0)));
      draw_ring(canvas, mid, e.swatch.h / 2 - 3, true);
      break;
    case LegendEntry::Symbol::kFeatureOutline: {
      swatch.setTo(cv::Scalar(jet(0.0, 1.0)));
      cv::Mat overlay = swatch.clone();
      cv::rectangle(overlay, {6, 6}, {e.swatch.w - 7, e.swatch.h - 7}, kOutline, 1, cv::LINE_AA);
      cv::addWeighted(overlay, kOutlineOpacity, swatch, 1.0 - kOutlineOpacity, 0.0, swatch);
      break;
    }
    case LegendEntry::Symbol::kNoSurface:
      swatch.setTo(kWhite);
      cv::rectangle(canvas, rect(e.swatch), kNoSurfaceBorder, 1);
      break;
  }
  draw_text(canvas, e.text);
}

}  // namespace

cv::Mat render_report(const detect::Detection& det, const ReportLayout& L) {
  cv::Mat canvas(L.height, L.width, CV_8UC3, kWhite);
  for (const auto& t : L.title) draw_text(canvas, t);
  const std::vector<PanelMap> maps = panel_maps(det);
  for (std::size_t p = 0; p < maps.size(); ++p) {
    const PanelLayout& panel = L.panels[p];
    draw_text(canvas, panel.title_text);
    cv::Mat image = deviation_image(maps[p], L.range, panel.map);
    draw_feature_outlines(image, maps[p], det, panel.scale);
    image.copyTo(canvas(rect(panel.map)));
    cv::rectangle(canvas, rect(panel.map), kNoSurfaceBorder, 1);
  }
  for (const DefectMark& m : L.marks) draw_ring(canvas, {m.cx, m.cy}, m.radius, m.echo);
  for (const DefectMark& m : L.marks) draw_number(canvas, m.label, m.echo);
  // Scale bar: black and white halves, ticks at its ends.
  cv::rectangle(canvas, rect(L.scale_bar), kBlack, cv::FILLED);
  cv::rectangle(canvas, {L.scale_bar.x + L.scale_bar.w / 2 + 1, L.scale_bar.y + 1},
                {L.scale_bar.right() - 2, L.scale_bar.bottom() - 2}, kWhite, cv::FILLED);
  draw_text(canvas, L.scale_bar_text);
  // Colour bar, +range at the top.
  draw_text(canvas, L.colour_title);
  for (int i = 0; i < L.colour_bar.h; ++i) {
    const double d = L.range * (1.0 - 2.0 * i / (L.colour_bar.h - 1));
    const cv::Vec3b v = jet(d, L.range);
    cv::line(canvas, {L.colour_bar.x, L.colour_bar.y + i}, {L.colour_bar.right() - 1, L.colour_bar.y + i},
             cv::Scalar(v[0], v[1], v[2]));
  }
  for (int t = 0; t < 5; ++t) {
    const int yt = L.colour_bar.y + (L.colour_bar.h - 1) * t / 4;
    cv::line(canvas, {L.colour_bar.right(), yt}, {L.colour_bar.right() + 6, yt}, kBlack);
  }
  for (const auto& t : L.colour_ticks) draw_text(canvas, t);
  for (const auto& e : L.legend) draw_legend(canvas, e);
  draw_text(canvas, L.table_title);
  for (std::size_t r = 0; r < L.table.size(); ++r) {
    for (const auto& cell : L.table[r]) draw_text(canvas, cell);
    if (r == 0) {  // a rule under the header
      const Box& first = L.table[0].front().box;
      cv::line(canvas, {first.x, first.bottom() + 3}, {L.table[0].back().box.right(), first.bottom() + 3},
               kBlack);
    }
  }
  draw_text(canvas, L.table_more);
  return canvas;
}

void write_report_png(const std::string& path, const detect::Detection& det, const ReportInfo& info) {
  if (det.map.size() == 0) throw ReportError(path + ": nothing to draw");
  const cv::Mat canvas = render_report(det, layout_report(det, info));
  try {
    files::write_atomically_with(path,
                                 [&](const std::filesystem::path& tmp) { image::write_png(tmp, canvas); });
  } catch (const image::ImageError& e) {
    throw ReportError(path + ": cannot write the PNG (" + e.what() + ")");
  } catch (const files::FileError& e) {
    throw ReportError(e.what());
  }
}

std::vector<std::array<std::uint8_t, 3>> marked_vertex_colours(const ingest::MeshView& mesh,
                                                               const detect::Detection& det) {
  const std::vector<PanelMap> panels = panel_maps(det);
  std::vector<std::array<std::uint8_t, 3>> colours(mesh.vertex_count(), {190, 190, 190});
  for (std::size_t i = 0; i < mesh.triangle_count(); ++i) {
    const auto t = mesh.triangle(i);
    const Eigen::Vector3d c =
        ((mesh.vertex(t[0]) + mesh.vertex(t[1]) + mesh.vertex(t[2])) / 3.0f).cast<double>();
    // The first map (chart) that labels the triangle's pixel: a chart labels only what it owns.
    int l = -1;
    for (const PanelMap& panel : panels) {
      const Eigen::Vector3d q = panel.map.to_map(c);
      const long k = panel.map.pixel_of(q.x(), q.y());
      if (k >= 0 && panel.labels[static_cast<std::size_t>(k)] != -1) {
        l = panel.labels[static_cast<std::size_t>(k)];
        break;
      }
    }
    std::array<std::uint8_t, 3> col;
    if (l >= 0) {
      col = det.defects[static_cast<std::size_t>(l)].defect.defect_class == protocol::DefectClass::kDent
                ? std::array<std::uint8_t, 3>{220, 30, 30}
                : std::array<std::uint8_t, 3>{30, 60, 230};
    } else if (detect::is_feature_label(l) && det.features[detect::feature_index(l)].defect.defect_class ==
                                                  protocol::DefectClass::kDesignFeature) {
      col = {230, 200, 60};
    } else {
      continue;
    }
    for (auto v : t) colours[v] = col;
  }
  return colours;
}

void write_marked_ply(const std::string& path, const ingest::MeshView& mesh, const detect::Detection& det) {
  const auto colours = marked_vertex_colours(mesh, det);
  try {
    ingest::write_ply(path, mesh, colours);
  } catch (const ingest::IngestError& e) {
    throw ReportError(e.what());
  }
}

}  // namespace dentmark::report
