// Ingest: point clouds (XYZ, PTS, CSV): unorganised clouds meshed in the sensor view or in charts,
// organised clouds stitched row by row, the text variants tools write.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "dentmark/host/ingest/cloud_mesher.h"
#include "dentmark/host/ingest/read_mesh.h"
#include "ingest_files.h"

namespace dentmark::ingest {
namespace {

using namespace testing;

TEST(Ingest, UnorganisedPointCloudIsMeshedInTheSensorView) {
  // A 60 x 60 jittered grid on a tilted plane 1 m in front of the sensor, shuffled.
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> j(-0.15f, 0.15f);
  std::vector<Eigen::Vector3f> pts;
  const float s = 0.001f;
  for (int y = 0; y < 60; ++y)
    for (int x = 0; x < 60; ++x) {
      const float px = (x + j(rng)) * s, py = (y + j(rng)) * s;
      pts.emplace_back(px, py, 1.0f + 0.2f * px);
    }
  std::shuffle(pts.begin(), pts.end(), rng);
  std::string xyz;
  for (auto& p : pts)
    xyz += std::to_string(p.x()) + "," + std::to_string(p.y()) + "," + std::to_string(p.z()) + " 0.5\n";
  const Mesh m = read_mesh(write_file("f.xyz", xyz));
  EXPECT_TRUE(m.from_point_cloud);
  EXPECT_EQ(m.cloud_charts, 0u);  // one view sees it all
  // Nearly the full grid's 2 x 59 x 59 triangles, none long, all facing one way.
  EXPECT_GT(m.triangles.size(), 0.85 * 2 * 59 * 59);
  EXPECT_LT(m.triangles.size(), 1.05 * 2 * 59 * 59);
  double area = 0.0;
  for (const auto& t : m.triangles) {
    const Eigen::Vector3f e1 = m.vertices[t[1]] - m.vertices[t[0]], e2 = m.vertices[t[2]] - m.vertices[t[0]];
    EXPECT_LT(std::max(e1.norm(), e2.norm()), 4 * s);
    area += 0.5 * e1.cross(e2).norm();
  }
  const double full = 0.059 * 0.059 * std::sqrt(1.04);
  EXPECT_NEAR(area, full, 0.1 * full);
}

TEST(Ingest, ACloudThatWrapsRoundIsMeshedInCharts) {
  // 260 degrees of a 0.15 m tube, 0.2 m long, 0.9 m in front of the sensor, as views
  // merged round it give it (points shuffled, 20 um of noise): in the sensor's image its
  // sides fold over, and one Delaunay triangulation there left them unmeshed or bridged
  // the back to the front. Meshed in charts, every triangle lies on the tube and faces the
  // way its neighbours do, and the mesh covers the whole tube once.
  const double R = 0.15, arc = 260.0 * std::numbers::pi / 180.0, step = 0.001;
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> jitter(-0.2, 0.2);
  std::normal_distribution<double> noise(0.0, 2e-5);
  Mesh m;
  const Eigen::Vector3d axis_point(0.0, 0.0, 0.9 + R);  // the tube's axis runs along y
  const auto radial = [&](const Eigen::Vector3f& p) {
    Eigen::Vector3d d = p.cast<double>() - axis_point;
    d.y() = 0.0;
    return d;
  };
  const int ns = static_cast<int>(arc * R / step), nt = static_cast<int>(0.2 / step);
  for (int j = 0; j < nt; ++j)
    for (int i = 0; i < ns; ++i) {
      const double a = -0.5 * arc + (i + jitter(rng)) * step / R, r = R + noise(rng);
      m.vertices.emplace_back(static_cast<float>(r * std::sin(a)),
                              static_cast<float>(-0.1 + (j + jitter(rng)) * step),
                              static_cast<float>(axis_point.z() - r * std::cos(a)));
    }
  std::shuffle(m.vertices.begin(), m.vertices.end(), rng);
  mesh_point_cloud(m);
  EXPECT_GE(m.cloud_charts, 3u);
  double area = 0.0;
  std::size_t outwards = 0, off_surface = 0;
  std::vector<char> used(m.vertices.size(), 0);
  for (const auto& t : m.triangles) {
    for (const auto v : t) used[v] = 1;
    const Eigen::Vector3f e1 = m.vertices[t[1]] - m.vertices[t[0]], e2 = m.vertices[t[2]] - m.vertices[t[0]];
    EXPECT_LT(std::max(e1.norm(), e2.norm()), 4 * step);
    const Eigen::Vector3d n = e1.cross(e2).cast<double>();
    area += 0.5 * n.norm();
    const Eigen::Vector3d out = radial(m.vertices[t[0]]).normalized();
    outwards += n.dot(out) > 0.0;
    off_surface += std::abs(n.normalized().dot(out)) < std::cos(0.35);  // 20 degrees
  }
  const double full = arc * R * 0.2;
  EXPECT_NEAR(area, full, 0.03 * full);
  // One way round: outwards, as the side facing the sensor does.
  EXPECT_EQ(outwards, m.triangles.size());
  EXPECT_LT(off_surface, m.triangles.size() / 1000);
  EXPECT_GT(std::count(used.begin(), used.end(), 1), static_cast<std::ptrdiff_t>(0.995 * m.vertices.size()));
}

TEST(Ingest, OrganisedCloudIsStitchedRowByRowAtAnyDensity) {
  // A panel at 55 degrees to the view, sampled evenly on its surface: its far end is
  // twice as dense in the image as its near end, and no one grid cell fits both (the
  // grid lost points at one end and left holes at the other: a 2.6 M-point cloud gave
  // 2 246 findings of noise and borders). Written in raster order, as a camera does,
  // its rows are stitched: every point kept, no hole, no long triangle.
  const int n = 150;
  const float s = 0.001f, c = std::cos(0.96f), sn = std::sin(0.96f);
  std::vector<Eigen::Vector3f> pts;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const float px = (x - n / 2) * s, py = (y - n / 2) * s;
      pts.emplace_back(px * c, py, 0.5f + px * sn);
    }
  std::string xyz;
  for (const auto& p : pts)
    xyz += std::to_string(p.x()) + " " + std::to_string(p.y()) + " " + std::to_string(p.z()) + "\n";
  const Mesh m = read_mesh(write_file("raster.xyz", xyz));
  EXPECT_EQ(m.triangles.size(), 2u * (n - 1) * (n - 1));
  double area = 0.0;
  for (const auto& t : m.triangles) {
    const Eigen::Vector3f e1 = m.vertices[t[1]] - m.vertices[t[0]], e2 = m.vertices[t[2]] - m.vertices[t[0]];
    EXPECT_LT(std::max(e1.norm(), e2.norm()), 2 * s);
    area += 0.5 * e1.cross(e2).norm();
  }
  const double full = std::pow((n - 1) * s, 2);
  EXPECT_NEAR(area, full, 0.01 * full);
  // Every triangle faces the sensor at the origin.
  for (const auto& t : m.triangles)
    EXPECT_GT((m.vertices[t[1]] - m.vertices[t[0]])
                  .cross(m.vertices[t[2]] - m.vertices[t[0]])
                  .dot(-m.vertices[t[0]]),
              0.0f);
}

TEST(Ingest, UnorganisedCloudKeepsEveryPointAtAnyDensity) {
  // The same 55-degree panel, its points in random order (a merged or filtered cloud):
  // the grid of one cell size kept one point per cell, losing a fifth of them at the
  // dense end and leaving holes at the sparse end. The Delaunay triangulation in the
  // image keeps every point, without holes or long triangles; above 200 000 points it is
  // made in strips, one per thread, which must join without gaps or doubled triangles.
  for (const int n : {150, 460}) {
    const float s = 0.001f, c = std::cos(0.96f), sn = std::sin(0.96f);
    std::mt19937 rng(9);
    std::uniform_real_distribution<float> j(-0.1f, 0.1f);
    Mesh m;
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const float px = (x - n / 2 + j(rng)) * s, py = (y - n / 2 + j(rng)) * s;
        m.vertices.emplace_back(px * c, py, 0.5f + px * sn);
      }
    std::shuffle(m.vertices.begin(), m.vertices.end(), rng);
    mesh_point_cloud(m);
    EXPECT_EQ(m.cloud_charts, 0u);  // at 55 degrees to the view: no fold
    std::vector<char> used(m.vertices.size(), 0);
    std::vector<std::array<std::uint32_t, 3>> sorted;
    double area = 0.0;
    for (const auto& t : m.triangles) {
      for (const auto v : t) used[v] = 1;
      auto k = t;
      std::sort(k.begin(), k.end());
      sorted.push_back(k);
      const Eigen::Vector3f e1 = m.vertices[t[1]] - m.vertices[t[0]],
                            e2 = m.vertices[t[2]] - m.vertices[t[0]];
      // (Along the jittered edge of the panel a triangle may span two samples.)
      EXPECT_LT(std::max(e1.norm(), e2.norm()), 2.5 * s);
      area += 0.5 * e1.cross(e2).norm();
      EXPECT_GT(e1.cross(e2).dot(-m.vertices[t[0]]), 0.0f);  // facing the sensor
    }
    EXPECT_EQ(std::count(used.begin(), used.end(), 1), static_cast<std::ptrdiff_t>(used.size())) << n;
    std::sort(sorted.begin(), sorted.end());
    EXPECT_EQ(std::adjacent_find(sorted.begin(), sorted.end()), sorted.end()) << n;
    const double full = std::pow((n - 1) * s, 2);
    EXPECT_NEAR(area, full, 0.01 * full) << n;
  }
}

// A 40 x 40 jittered grid on a tilted plane 1 m in front of the sensor (metres).
std::vector<Eigen::Vector3f> cloud_points() {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> j(-0.15f, 0.15f);
  std::vector<Eigen::Vector3f> pts;
  for (int y = 0; y < 40; ++y)
    for (int x = 0; x < 40; ++x) {
      const float px = (x + j(rng)) * 0.001f, py = (y + j(rng)) * 0.001f;
      pts.emplace_back(px, py, 1.0f + 0.2f * px);
    }
  return pts;
}

// The same points written as 'x<sep>y<sep>z' with 'decimal' as the decimal mark.
std::string cloud_text(const std::vector<Eigen::Vector3f>& pts, const std::string& sep, char decimal = '.') {
  std::string out;
  char buf[64];
  for (const auto& p : pts) {
    std::snprintf(buf, sizeof buf, "%.7f%s%.7f%s%.7f%s0.5\n", p.x(), sep.c_str(), p.y(), sep.c_str(), p.z(),
                  sep.c_str());
    std::string line = buf;
    if (decimal != '.') std::replace(line.begin(), line.end(), '.', decimal);
    out += line;
  }
  return out;
}

TEST(Ingest, PointCloudsAsToolsWriteThem) {
  // Headers (column names, a Leica .pts count), semicolons, decimal commas, a UTF-8 byte
  // order mark: each reads the same points as the plain file.
  const std::vector<Eigen::Vector3f> pts = cloud_points();
  const Mesh plain = read_mesh(write_file("g0.xyz", cloud_text(pts, " ")));
  ASSERT_EQ(plain.input_points, pts.size());
  const auto same = [&](const Mesh& m) {
    ASSERT_EQ(m.vertices.size(), plain.vertices.size());
    for (std::size_t i = 0; i < m.vertices.size(); ++i) EXPECT_EQ(m.vertices[i], plain.vertices[i]) << i;
    EXPECT_EQ(m.triangles.size(), plain.triangles.size());
  };
  for (const auto& [name, text] : std::vector<std::pair<std::string, std::string>>{
           {"g1.csv", "X,Y,Z,Intensity\n" + cloud_text(pts, ",")},
           {"g2.pts", std::to_string(pts.size()) + "\n" + cloud_text(pts, " ")},
           {"g3.csv", "x;y;z;i\r\n" + cloud_text(pts, ";")},
           {"g4.csv", cloud_text(pts, ";", ',')},
           {"g5.txt", "X\tY\tZ\n" + cloud_text(pts, "\t", ',')},
           {"g6.xyz", "\xEF\xBB\xBF" + cloud_text(pts, ", ")},
           {"g7.xyz", "# exported\n// x y z\n" + cloud_text(pts, " ")}}) {
    SCOPED_TRACE(name);
    same(read_mesh(write_file(name, text)));
  }
  // Only the first line may be a header: a later line without three numbers is an error
  // naming it.
  try {
    read_mesh(write_file("g8.xyz", "X Y Z\n" + cloud_text(pts, " ") + "1.0 2.0 oops\n"));
    FAIL() << "no error";
  } catch (const IngestError& e) {
    EXPECT_NE(std::string(e.what()).find("line " + std::to_string(pts.size() + 2) + ":"), std::string::npos)
        << e.what();
  }
}

TEST(Ingest, OrganisedCloudsMarkMissingPixelsAtTheSensor) {
  // An organised cloud (a point per camera pixel) may write a pixel without a
  // measurement as (0, 0, 0) instead of NaN: it reads as NaN, and the rest is meshed.
  std::vector<Eigen::Vector3f> pts = cloud_points();
  std::string with_nan, with_zero;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const bool missing = i % 7 == 3;
    char buf[96];
    std::snprintf(buf, sizeof buf, "%.7f %.7f %.7f\n", pts[i].x(), pts[i].y(), pts[i].z());
    with_nan += missing ? "nan nan nan\n" : buf;
    with_zero += missing ? "0 0 0\n" : buf;
  }
  const Mesh a = read_mesh(write_file("h0.xyz", with_nan)), b = read_mesh(write_file("h1.xyz", with_zero));
  EXPECT_EQ(a.nonfinite_vertices, (pts.size() + 3) / 7);
  EXPECT_EQ(b.nonfinite_vertices, a.nonfinite_vertices);
  ASSERT_EQ(a.triangles.size(), b.triangles.size());
  EXPECT_EQ(a.triangles, b.triangles);
  EXPECT_GT(a.triangles.size(), 1500u);  // of 2 x 39 x 39 = 3042 with every point there
}

}  // namespace
}  // namespace dentmark::ingest
