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

// One height map with its deviation and labels: the scan's, or one of its charts'.
struct Panel {
  const detect::HeightMap& map;
  const std::vector<float>& deviation;
  const std::vector<std::int32_t>& labels;
};

std::vector<Panel> panels_of(const detect::Detection& det) {
  std::vector<Panel> panels{{det.map, det.deviation, det.labels}};
  for (const auto& c : det.more_charts) panels.push_back({c.map, c.deviation, c.labels});
  return panels;
}

// The deviation as colours (JET over +-range), about 1600 px wide, with the findings
// defect_here and feature_here mark as the panel's ringed.
cv::Mat render_panel(const Panel& panel, double range, const detect::Detection& det,
                     const std::vector<bool>& defect_here, const std::vector<bool>& feature_here) {
  const auto& map = panel.map;
  cv::Mat grey(map.rows, map.cols, CV_8U), empty(map.rows, map.cols, CV_8U, cv::Scalar(0));
  for (int r = 0; r < map.rows; ++r)
    for (int c = 0; c < map.cols; ++c) {
      const float d = panel.deviation[static_cast<std::size_t>(r) * map.cols + c];
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
  colour.setTo(cv::Scalar(255, 255, 255), empty);
  // Scale so that the picture is about 1600 px wide.
  const double scale = std::clamp(1600.0 / map.cols, 0.25, 8.0);
  cv::Mat big;
  cv::resize(colour, big, {}, scale, scale, scale >= 1 ? cv::INTER_NEAREST : cv::INTER_AREA);
  auto draw = [&](const detect::Finding& f, const cv::Scalar& col, bool label) {
    const Eigen::Vector3d q = map.to_map(f.defect.position);
    const cv::Point p(static_cast<int>((q.x() - map.u0) / map.pixel * scale),
                      static_cast<int>((q.y() - map.v0) / map.pixel * scale));
    const int rad = std::max(10, static_cast<int>(0.75 * f.defect.diameter / map.pixel * scale));
    cv::circle(big, p, rad, col, 2, cv::LINE_AA);
    if (label) {
      char text[64];
      std::snprintf(text, sizeof text, "#%u %s %+.3f mm", f.defect.id,
                    f.defect.defect_class == protocol::DefectClass::kDent ? "dent" : "bump",
                    1e3 * f.defect.height);
      cv::putText(big, text, p + cv::Point(rad + 4, 5), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 3,
                  cv::LINE_AA);
      cv::putText(big, text, p + cv::Point(rad + 4, 5), cv::FONT_HERSHEY_SIMPLEX, 0.5, col, 1, cv::LINE_AA);
    }
  };
  for (std::size_t k = 0; k < det.features.size(); ++k)
    if (feature_here[k] && det.features[k].defect.defect_class == protocol::DefectClass::kDesignFeature)
      draw(det.features[k], cv::Scalar(128, 128, 128), false);
  for (std::size_t k = 0; k < det.defects.size(); ++k)
    if (defect_here[k]) draw(det.defects[k], cv::Scalar(255, 0, 255), true);
  return big;
}

}  // namespace

void write_report_png(const std::string& path, const detect::Detection& det) {
  if (det.map.size() == 0) throw ReportError(path + ": nothing to draw");
  const std::vector<Panel> panels = panels_of(det);
  // Each finding on the panel (chart) whose labels hold it; one on none (or a scan seen
  // in one map) on the first.
  std::vector<std::vector<bool>> defect_here(panels.size(), std::vector<bool>(det.defects.size(), false));
  std::vector<std::vector<bool>> feature_here(panels.size(), std::vector<bool>(det.features.size(), false));
  if (panels.size() > 1)
    for (std::size_t p = 0; p < panels.size(); ++p)
      for (const std::int32_t l : panels[p].labels) {
        if (l >= 0) defect_here[p][static_cast<std::size_t>(l)] = true;
        if (l <= -2) feature_here[p][static_cast<std::size_t>(-2 - l)] = true;
      }
  for (auto* here : {&defect_here, &feature_here})
    for (std::size_t k = 0; k < (*here)[0].size(); ++k)
      if (std::none_of(here->begin(), here->end(), [&](const std::vector<bool>& panel) { return panel[k]; }))
        (*here)[0][k] = true;
  // Colour range: the larger of 0.1 mm and 8x the measured deviation noise.
  const double range = std::max(1e-4, 8.0 * det.stats.deviation_noise);
  std::vector<cv::Mat> pictures;
  int width = 0, height = 0;
  const int title_h = panels.size() > 1 ? 30 : 0;
  for (std::size_t p = 0; p < panels.size(); ++p) {
    pictures.push_back(render_panel(panels[p], range, det, defect_here[p], feature_here[p]));
    width = std::max(width, pictures.back().cols);
    height += pictures.back().rows + title_h;
  }
  const int legend_w = 160;
  cv::Mat canvas(std::max(height, 420), width + legend_w, CV_8UC3, cv::Scalar(255, 255, 255));
  int y = 0;
  for (std::size_t p = 0; p < pictures.size(); ++p) {
    if (title_h > 0) {
      const std::string title = "chart " + std::to_string(p + 1) + " of " + std::to_string(pictures.size()) +
                                " (the surface wraps round: each chart seen face-on)";
      cv::putText(canvas, title, {10, y + 21}, cv::FONT_HERSHEY_SIMPLEX, 0.6, cv::Scalar(0, 0, 0), 1,
                  cv::LINE_AA);
      y += title_h;
    }
    pictures[p].copyTo(canvas(cv::Rect(0, y, pictures[p].cols, pictures[p].rows)));
    y += pictures[p].rows;
  }
  // Legend: colour bar in mm.
  const int x0 = width + 30, y0 = 40, bar_h = 320;
  for (int i = 0; i < bar_h; ++i) {
    cv::Mat px(1, 1, CV_8U, cv::Scalar(255 - 255 * i / (bar_h - 1))), c;
    cv::applyColorMap(px, c, cv::COLORMAP_JET);
    const cv::Vec3b v = c.at<cv::Vec3b>(0, 0);
    cv::line(canvas, {x0, y0 + i}, {x0 + 24, y0 + i}, cv::Scalar(v[0], v[1], v[2]));
  }
  cv::putText(canvas, "deviation", {x0 - 10, y0 - 22}, cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 1,
              cv::LINE_AA);
  for (int t = -2; t <= 2; ++t) {
    const int yt = y0 + (bar_h - 1) * (2 - t) / 4;
    char text[32];
    std::snprintf(text, sizeof text, "%+.3f mm", 1e3 * range * t / 2.0);
    cv::line(canvas, {x0 + 24, yt}, {x0 + 30, yt}, cv::Scalar(0, 0, 0));
    cv::putText(canvas, text, {x0 + 34, yt + 5}, cv::FONT_HERSHEY_SIMPLEX, 0.42, cv::Scalar(0, 0, 0), 1,
                cv::LINE_AA);
  }
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
  const std::vector<Panel> panels = panels_of(det);
  std::vector<std::array<std::uint8_t, 3>> colours(mesh.vertex_count(), {190, 190, 190});
  for (std::size_t i = 0; i < mesh.triangle_count(); ++i) {
    const auto t = mesh.triangle(i);
    const Eigen::Vector3d c =
        ((mesh.vertex(t[0]) + mesh.vertex(t[1]) + mesh.vertex(t[2])) / 3.0f).cast<double>();
    // The first map (chart) that labels the triangle's pixel: a chart labels only what it owns.
    int l = -1;
    for (const Panel& panel : panels) {
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
    } else if (l <= -2 && det.features[static_cast<std::size_t>(-2 - l)].defect.defect_class ==
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
