#include "dentmark/host/report/pictures.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/imgproc.hpp>

#include "dentmark/common/image/png_io.h"
#include "dentmark/host/ingest/mesh_writer.h"
#include "dentmark/host/report/defects_json.h"

namespace dentmark::report {

void write_report_png(const std::string& path, const detect::Detection& det) {
  const auto& map = det.map;
  if (map.size() == 0) throw ReportError(path + ": nothing to draw");
  // Colour range: the larger of 0.1 mm and 8x the measured deviation noise.
  const double range = std::max(1e-4, 8.0 * det.stats.deviation_noise);
  cv::Mat grey(map.rows, map.cols, CV_8U), empty(map.rows, map.cols, CV_8U, cv::Scalar(0));
  for (int r = 0; r < map.rows; ++r)
    for (int c = 0; c < map.cols; ++c) {
      const float d = det.deviation[static_cast<std::size_t>(r) * map.cols + c];
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
  const int legend_w = 160;
  cv::Mat canvas(std::max(big.rows, 420), big.cols + legend_w, CV_8UC3, cv::Scalar(255, 255, 255));
  big.copyTo(canvas(cv::Rect(0, 0, big.cols, big.rows)));
  auto draw = [&](const detect::Finding& f, const cv::Scalar& col, bool label) {
    const Eigen::Vector3d q = map.to_map(f.defect.position);
    const cv::Point p(static_cast<int>((q.x() - map.u0) / map.pixel * scale),
                      static_cast<int>((q.y() - map.v0) / map.pixel * scale));
    const int rad = std::max(10, static_cast<int>(0.75 * f.defect.diameter / map.pixel * scale));
    cv::circle(canvas, p, rad, col, 2, cv::LINE_AA);
    if (label) {
      char text[64];
      std::snprintf(text, sizeof text, "#%u %s %+.3f mm", f.defect.id,
                    f.defect.defect_class == protocol::DefectClass::kDent ? "dent" : "bump",
                    1e3 * f.defect.height);
      cv::putText(canvas, text, p + cv::Point(rad + 4, 5), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0),
                  3, cv::LINE_AA);
      cv::putText(canvas, text, p + cv::Point(rad + 4, 5), cv::FONT_HERSHEY_SIMPLEX, 0.5, col, 1,
                  cv::LINE_AA);
    }
  };
  for (const auto& f : det.features)
    if (f.defect.defect_class == protocol::DefectClass::kDesignFeature)
      draw(f, cv::Scalar(128, 128, 128), false);
  for (const auto& f : det.defects) draw(f, cv::Scalar(255, 0, 255), true);
  // Legend: colour bar in mm.
  const int x0 = big.cols + 30, y0 = 40, bar_h = 320;
  for (int i = 0; i < bar_h; ++i) {
    cv::Mat px(1, 1, CV_8U, cv::Scalar(255 - 255 * i / (bar_h - 1))), c;
    cv::applyColorMap(px, c, cv::COLORMAP_JET);
    const cv::Vec3b v = c.at<cv::Vec3b>(0, 0);
    cv::line(canvas, {x0, y0 + i}, {x0 + 24, y0 + i}, cv::Scalar(v[0], v[1], v[2]));
  }
  cv::putText(canvas, "deviation", {x0 - 10, y0 - 22}, cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 1,
              cv::LINE_AA);
  for (int t = -2; t <= 2; ++t) {
    const int y = y0 + (bar_h - 1) * (2 - t) / 4;
    char text[32];
    std::snprintf(text, sizeof text, "%+.3f mm", 1e3 * range * t / 2.0);
    cv::line(canvas, {x0 + 24, y}, {x0 + 30, y}, cv::Scalar(0, 0, 0));
    cv::putText(canvas, text, {x0 + 34, y + 5}, cv::FONT_HERSHEY_SIMPLEX, 0.42, cv::Scalar(0, 0, 0), 1,
                cv::LINE_AA);
  }
  const std::string tmp = path + ".tmp.png";
  try {
    image::write_png(tmp, canvas);
  } catch (const image::ImageError& e) {
    std::remove(tmp.c_str());
    throw ReportError(path + ": cannot write the PNG (" + e.what() + ")");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw ReportError(path + ": cannot rename: " + ec.message());
}

void write_marked_ply(const std::string& path, const ingest::MeshView& mesh, const detect::Detection& det) {
  const auto& map = det.map;
  std::vector<std::array<std::uint8_t, 3>> colours(mesh.vertex_count(), {190, 190, 190});
  for (std::size_t i = 0; i < mesh.triangle_count(); ++i) {
    const auto t = mesh.triangle(i);
    const Eigen::Vector3d c =
        ((mesh.vertex(t[0]) + mesh.vertex(t[1]) + mesh.vertex(t[2])) / 3.0f).cast<double>();
    const Eigen::Vector3d q = map.to_map(c);
    const long k = map.pixel_of(q.x(), q.y());
    if (k < 0) continue;
    const int l = det.labels[static_cast<std::size_t>(k)];
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
  try {
    ingest::write_ply(path, mesh, colours);
  } catch (const ingest::IngestError& e) {
    throw ReportError(e.what());
  }
}

}  // namespace dentmark::report
