// The report PNG: every mark, label, legend entry and table row lies inside the image;
// the table has a row per defect with its figures; the scale bar is as long as it says;
// the drawing puts ink where the layout says and design features are outlined, not ringed.
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

#include "dentmark/host/detect/detector.h"
#include "dentmark/host/report/pictures.h"
#include "dentmark/host/report/report_layout.h"
#include "dentmark/sim/scan/sls_scan.h"

namespace dentmark::report {
namespace {

detect::Detection small_door_detection() {
  sim::scan::ScanOptions o;
  o.seed = 21;
  o.shape.width = 0.3;
  o.shape.height = 0.25;
  o.spacing = 0.001;
  o.defects = 0;
  o.shape.window = o.shape.crease = o.shape.handle = false;  // the defects alone
  o.planted = {{{0.08, 0.07}, 0.015, -3e-4}, {{0.2, 0.12}, 0.018, 3e-4}, {{0.1, 0.18}, 0.014, -4e-4}};
  const sim::scan::SynthScan scan = sim::scan::synthesize_scan(o);
  ingest::Mesh mesh;
  mesh.vertices = scan.vertices;
  mesh.triangles = scan.triangles;
  return detect::detect(mesh, detect::DetectConfig{});
}

// Defects at the map's four corners: their rings and numbers must stay on the canvas.
void add_corner_defects(detect::Detection& det) {
  const auto& m = det.map;
  std::uint32_t id = static_cast<std::uint32_t>(det.defects.size()) + 1;
  for (const auto& [c, r] :
       {std::pair{0.0, 0.0}, {m.cols - 0.5, 0.0}, {0.0, m.rows - 0.5}, {m.cols - 0.5, m.rows - 0.5}}) {
    detect::Finding f;
    f.defect.id = id++;
    f.defect.defect_class = protocol::DefectClass::kDent;
    f.defect.position = m.to_scan(m.u0 + c * m.pixel, m.v0 + r * m.pixel, 0.0);
    f.defect.diameter = 0.03;
    f.defect.height = -1e-4;
    det.defects.push_back(f);
  }
}

bool inside(const Box& b, const ReportLayout& L) {
  return b.x >= 0 && b.y >= 0 && b.right() <= L.width && b.bottom() <= L.height;
}

TEST(Report, EverythingIsInsideTheImageAndTheTableHasARowPerDefect) {
  detect::Detection det = small_door_detection();
  ASSERT_EQ(det.defects.size(), 3u);
  const std::size_t found = det.defects.size();
  add_corner_defects(det);
  const ReportLayout L = layout_report(det, {"door.pcd", "2026-12-06 02:30 UTC"});
  ASSERT_GT(L.width, 1000);
  ASSERT_GT(L.height, 600);
  // Title: file and date, the counts, then spacing and noise.
  ASSERT_EQ(L.title.size(), 3u);
  EXPECT_EQ(L.title[0].text, "door.pcd   scanned 2026-12-06 02:30 UTC");
  EXPECT_NE(L.title[1].text.find(std::to_string(found + 4) + " defects ("), std::string::npos)
      << L.title[1].text;
  EXPECT_NE(L.title[2].text.find("point spacing 1.0"), std::string::npos) << L.title[2].text;
  EXPECT_NE(L.title[2].text.find("deviation noise 0.0"), std::string::npos) << L.title[2].text;
  for (const auto& t : L.title) EXPECT_TRUE(inside(t.box, L)) << t.text;

  // Table: a header and a row per defect with its id, class, diameter, depth, position.
  ASSERT_EQ(L.table.size(), det.defects.size() + 1);
  EXPECT_EQ(L.table[0][0].text, "#");
  EXPECT_EQ(L.table[0][3].text, "depth mm");
  for (std::size_t k = 0; k < det.defects.size(); ++k) {
    const auto& d = det.defects[k].defect;
    const auto& row = L.table[k + 1];
    ASSERT_EQ(row.size(), 7u);
    EXPECT_EQ(row[0].text, std::to_string(d.id));
    EXPECT_EQ(row[1].text, d.defect_class == protocol::DefectClass::kDent ? "dent" : "bump");
    EXPECT_NEAR(std::stod(row[2].text), 1e3 * d.diameter, 0.051);
    EXPECT_NEAR(std::stod(row[3].text), 1e3 * std::abs(d.height), 0.0051);
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(std::stod(row[4 + a].text), 1e3 * d.position[a], 0.051);
    for (const auto& cell : row) EXPECT_TRUE(inside(cell.box, L)) << cell.text;
    EXPECT_GT(row[0].box.y, L.table[k][0].box.y);  // rows go down the page
  }
  EXPECT_TRUE(L.table_more.text.empty());

  // Marks: a ring and a number per defect; the numbers inside their panel, apart.
  ASSERT_EQ(L.marks.size(), det.defects.size());
  for (std::size_t k = 0; k < L.marks.size(); ++k) {
    const DefectMark& m = L.marks[k];
    EXPECT_FALSE(m.echo);
    EXPECT_TRUE(inside({m.cx - m.radius, m.cy - m.radius, 2 * m.radius + 1, 2 * m.radius + 1}, L)) << k;
    EXPECT_TRUE(m.label.box.inside(L.panels[m.panel].map)) << k;
    EXPECT_EQ(m.label.text, std::to_string(det.defects[k].defect.id));
    for (std::size_t j = 0; j < k; ++j)
      EXPECT_FALSE(m.label.box.overlaps(L.marks[j].label.box)) << k << " " << j;
  }
  // A found defect's ring is centred where the map puts it, as wide as it is.
  const auto& map = det.map;
  for (std::size_t k = 0; k < found; ++k) {
    const auto& d = det.defects[k].defect;
    const Eigen::Vector3d q = map.to_map(d.position);
    const PanelLayout& p = L.panels[0];
    EXPECT_NEAR(L.marks[k].cx, p.map.x + (q.x() - map.u0) / map.pixel * p.scale, 1.0);
    EXPECT_NEAR(L.marks[k].cy, p.map.y + (q.y() - map.v0) / map.pixel * p.scale, 1.0);
    EXPECT_NEAR(L.marks[k].radius, 0.5 * d.diameter / map.pixel * p.scale + 3, 1.0);
  }

  // Scale bar: as long as its label says at the map's scale.
  const PanelLayout& p = L.panels[0];
  EXPECT_NEAR(L.scale_bar.w, L.scale_bar_mm * 1e-3 / map.pixel * p.scale, 1.0);
  EXPECT_EQ(L.scale_bar_text.text, std::to_string(static_cast<int>(L.scale_bar_mm)) + " mm");
  EXPECT_GE(L.scale_bar.w, 0.15 * p.map.w);
  for (const Box& b :
       {L.scale_bar, L.scale_bar_text.box, L.colour_bar, L.colour_title.box, L.table_title.box, p.map})
    EXPECT_TRUE(inside(b, L));
  for (const auto& t : L.colour_ticks) EXPECT_TRUE(inside(t.box, L)) << t.text;
  ASSERT_EQ(L.legend.size(), 3u);  // one chart: no echoes to explain
  for (const auto& e : L.legend) EXPECT_TRUE(inside(e.swatch, L) && inside(e.text.box, L)) << e.text.text;
  // The side column does not cover the map.
  EXPECT_GE(L.colour_bar.x, p.map.right());
  EXPECT_GE(L.table[0][0].box.x, p.map.right());
}

// Dark pixels (text, rule, ring) inside a box of the canvas.
int ink(const cv::Mat& img, const Box& b) {
  int n = 0;
  for (int y = b.y; y < b.bottom(); ++y)
    for (int x = b.x; x < b.right(); ++x) {
      const cv::Vec3b v = img.at<cv::Vec3b>(y, x);
      n += v[0] < 80 && v[1] < 80 && v[2] < 80;
    }
  return n;
}

TEST(Report, TheDrawingPutsInkWhereTheLayoutSays) {
  detect::Detection det = small_door_detection();
  const ReportLayout L = layout_report(det, {"door.ply", "2026-12-06 02:30 UTC"});
  const cv::Mat img = render_report(det, L);
  ASSERT_EQ(img.cols, L.width);
  ASSERT_EQ(img.rows, L.height);
  for (const auto& row : L.table)
    for (const auto& cell : row) EXPECT_GT(ink(img, cell.box), 3) << cell.text;
  for (const auto& t : L.title) EXPECT_GT(ink(img, t.box), 50) << t.text;
  for (const auto& m : L.marks) {
    EXPECT_GT(ink(img, m.label.box), 5) << m.label.text;
    // The ring's rightmost point is black.
    EXPECT_GT(ink(img, {m.cx + m.radius - 1, m.cy - 1, 3, 3}), 0);
  }
  EXPECT_GT(ink(img, L.scale_bar), L.scale_bar.w);
  // The margin round the canvas is blank: nothing runs off the edge.
  EXPECT_EQ(ink(img, {0, 0, L.width, 4}) + ink(img, {0, L.height - 4, L.width, 4}) +
                ink(img, {0, 0, 4, L.height}) + ink(img, {L.width - 4, 0, 4, L.height}),
            0);
}

TEST(Report, DesignFeaturesAreOutlinedNotRinged) {
  // The door's handle and window are design features.
  sim::scan::ScanOptions o;
  o.seed = 4;
  o.spacing = 0.002;
  o.defects = 0;
  const sim::scan::SynthScan scan = sim::scan::synthesize_scan(o);
  ingest::Mesh mesh;
  mesh.vertices = scan.vertices;
  mesh.triangles = scan.triangles;
  detect::Detection det = detect::detect(mesh, detect::DetectConfig{});
  std::size_t features = 0;
  for (const auto& f : det.features)
    features += f.defect.defect_class == protocol::DefectClass::kDesignFeature;
  ASSERT_GT(features, 0u);
  const ReportLayout L = layout_report(det, {"door.ply", ""});
  EXPECT_TRUE(L.marks.size() == det.defects.size());  // no ring for a feature
  // Drawn: the outline changes pixels on the feature's border and nowhere far from it.
  const cv::Mat with = render_report(det, L);
  detect::Detection plain = det;
  for (auto& f : plain.features) f.defect.defect_class = protocol::DefectClass::kNoise;
  const cv::Mat without = render_report(plain, L);
  cv::Mat diff;
  cv::absdiff(with, without, diff);
  cv::Mat changed;
  cv::cvtColor(diff, changed, cv::COLOR_BGR2GRAY);
  const int n = cv::countNonZero(changed > 10);
  EXPECT_GT(n, 100);
  // Lightly: a small share of the map, not discs over it.
  EXPECT_LT(n, 0.15 * L.panels[0].map.w * L.panels[0].map.h);
}

}  // namespace
}  // namespace dentmark::report
