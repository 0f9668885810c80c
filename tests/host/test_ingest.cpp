// Ingest: every format gives the same mesh; malformed files give one-line errors that
// name the file and the position, never a crash.
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cctype>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <numbers>
#include <random>
#include <string>
#include <system_error>
#include <tuple>
#include <vector>

#include "dentmark/common/ingest/mesh_writer.h"
#include "dentmark/host/ingest/cloud_mesher.h"
#include "dentmark/host/ingest/read_mesh.h"
#include "dentmark/host/ingest/units.h"

namespace dentmark::ingest {
namespace {

// One directory per test process, removed when the process ends, so that no run leaves
// files behind in /tmp.
class ScratchDir {
 public:
  ScratchDir()
      : path_(std::filesystem::temp_directory_path() / ("dentmark_ingest_" + std::to_string(::getpid()))) {
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

std::string temp_path(const std::string& name) {
  static const ScratchDir dir;
  return (dir.path() / name).string();
}

std::string write_file(const std::string& name, const std::string& bytes) {
  const std::string p = temp_path(name);
  std::ofstream(p, std::ios::binary) << bytes;
  return p;
}

template <typename T>
void put(std::string& s, T v, bool big = false) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  if (big) std::reverse(b, b + sizeof(T));
  s.append(b, sizeof(T));
}

// A unit square split in two plus a triangle: 5 vertices, 3 triangles after fans.
const float kV[5][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {2, 0, 1}};

void expect_reference(const Mesh& m, float scale = 1.0f) {
  ASSERT_EQ(m.vertices.size(), 5u);
  ASSERT_EQ(m.triangles.size(), 3u);
  for (int i = 0; i < 5; ++i)
    for (int a = 0; a < 3; ++a) EXPECT_FLOAT_EQ(m.vertices[i][a], kV[i][a] * scale);
  EXPECT_EQ(m.triangles[0], (std::array<std::uint32_t, 3>{0, 1, 2}));
  EXPECT_EQ(m.triangles[1], (std::array<std::uint32_t, 3>{0, 2, 3}));
  EXPECT_EQ(m.triangles[2], (std::array<std::uint32_t, 3>{1, 4, 2}));
}

std::string ascii_ply() {
  std::string s =
      "ply\nformat ascii 1.0\ncomment test\nelement vertex 5\nproperty float x\nproperty float y\n"
      "property float z\nproperty uchar red\nelement face 2\nproperty list uchar int vertex_indices\n"
      "end_header\n";
  for (auto& v : kV)
    s += std::to_string(v[0]) + " " + std::to_string(v[1]) + " " + std::to_string(v[2]) + " 7\n";
  s += "4 0 1 2 3\n3 1 4 2\n";
  return s;
}

std::string binary_ply(bool big, bool dbl, const char* count_type, const char* index_type) {
  std::string s = std::string("ply\nformat ") + (big ? "binary_big_endian" : "binary_little_endian") +
                  " 1.0\nelement vertex 5\nproperty " + (dbl ? "double" : "float") + " x\nproperty " +
                  (dbl ? "double" : "float") + " y\nproperty " + (dbl ? "double" : "float") +
                  " z\nproperty float confidence\nelement face 2\nproperty list " + count_type + " " +
                  index_type + " vertex_indices\nproperty uchar flags\nend_header\n";
  for (auto& v : kV) {
    for (int a = 0; a < 3; ++a) dbl ? put<double>(s, v[a], big) : put<float>(s, v[a], big);
    put<float>(s, 0.5f, big);
  }
  auto count = [&](int n) {
    if (std::string(count_type) == "uchar")
      put<std::uint8_t>(s, static_cast<std::uint8_t>(n));
    else
      put<std::int32_t>(s, n, big);
  };
  auto index = [&](int i) {
    if (std::string(index_type) == "int")
      put<std::int32_t>(s, i, big);
    else if (std::string(index_type) == "uint")
      put<std::uint32_t>(s, static_cast<std::uint32_t>(i), big);
    else
      put<std::uint16_t>(s, static_cast<std::uint16_t>(i), big);
  };
  count(4);
  for (int i : {0, 1, 2, 3}) index(i);
  put<std::uint8_t>(s, 1);
  count(3);
  for (int i : {1, 4, 2}) index(i);
  put<std::uint8_t>(s, 1);
  return s;
}

TEST(Ingest, AsciiPly) {
  expect_reference(read_mesh(write_file("a.ply", ascii_ply())));
}

TEST(Ingest, BinaryPlyAllEncodingsAndTypes) {
  for (bool big : {false, true})
    for (bool dbl : {false, true})
      for (const char* ct : {"uchar", "int"})
        for (const char* it : {"int", "uint", "ushort"}) {
          SCOPED_TRACE(std::string(big ? "BE " : "LE ") + (dbl ? "double " : "float ") + ct + " " + it);
          expect_reference(read_mesh(write_file("b.ply", binary_ply(big, dbl, ct, it))));
        }
}

// PLY allows its elements in any order: faces before the vertices they index read as
// the usual order does, in ASCII and binary; an index past the declared vertices fails.
TEST(Ingest, PlyFacesBeforeVertices) {
  const auto faces_first = [](const std::string& ply) {
    // Swap the two element blocks of the header and of the body.
    const std::size_t v = ply.find("element vertex"), f = ply.find("element face"),
                      h = ply.find("end_header\n") + 11;
    const std::string head =
        ply.substr(0, v) + ply.substr(f, h - 11 - f) + ply.substr(v, f - v) + "end_header\n";
    return std::pair{head, h};
  };
  {
    const std::string ply = ascii_ply();
    const auto [head, body] = faces_first(ply);
    const std::size_t faces = ply.find("4 0 1 2 3\n");
    expect_reference(
        read_mesh(write_file("ff.ply", head + ply.substr(faces) + ply.substr(body, faces - body))));
    std::string bad = head + "4 0 1 2 5\n3 1 4 2\n" + ply.substr(body, faces - body);
    EXPECT_THROW(
        {
          try {
            read_mesh(write_file("ff_bad.ply", bad));
          } catch (const IngestError& e) {
            EXPECT_NE(std::string(e.what()).find("vertex index 5 out of range (5 vertices)"),
                      std::string::npos)
                << e.what();
            throw;
          }
        },
        IngestError);
  }
  for (bool big : {false, true}) {
    const std::string ply = binary_ply(big, false, "uchar", "int");
    const auto [head, body] = faces_first(ply);
    const std::size_t vertex_bytes = 5 * 4 * sizeof(float);
    expect_reference(read_mesh(
        write_file("ffb.ply", head + ply.substr(body + vertex_bytes) + ply.substr(body, vertex_bytes))));
  }
}

TEST(Ingest, ObjWithPolygonsTexturesAndNegativeIndices) {
  std::string s = "# comment\no panel\n";
  for (auto& v : kV)
    s += "v " + std::to_string(v[0]) + " " + std::to_string(v[1]) + " " + std::to_string(v[2]) + "\n";
  s += "vn 0 0 1\nvt 0 0\nf 1/1/1 2/1/1 3/1/1 4/1/1\nf -4//1 -1//1 -3//1\n";
  expect_reference(read_mesh(write_file("c.obj", s)));
}

TEST(Ingest, StlAsciiAndBinary) {
  std::string a = "solid t\n", b(80, ' ');
  const int tris[3][3] = {{0, 1, 2}, {0, 2, 3}, {1, 4, 2}};
  put<std::uint32_t>(b, 3);
  for (auto& t : tris) {
    a += "facet normal 0 0 1\n outer loop\n";
    for (float f : {0.f, 0.f, 1.f}) put<float>(b, f);
    for (int i : t) {
      a += "  vertex " + std::to_string(kV[i][0]) + " " + std::to_string(kV[i][1]) + " " +
           std::to_string(kV[i][2]) + "\n";
      for (int k = 0; k < 3; ++k) put<float>(b, kV[i][k]);
    }
    a += " endloop\nendfacet\n";
    put<std::uint16_t>(b, 0);
  }
  a += "endsolid t\n";
  for (const auto& bytes : {a, b}) {
    const Mesh m = read_mesh(write_file("d.stl", bytes));
    ASSERT_EQ(m.triangles.size(), 3u);
    for (int t = 0; t < 3; ++t)
      for (int c = 0; c < 3; ++c)
        for (int k = 0; k < 3; ++k) EXPECT_FLOAT_EQ(m.vertices[m.triangles[t][c]][k], kV[tris[t][c]][k]);
    // The facets' nine corners are the five vertices they share (their edges link them).
    EXPECT_EQ(m.vertices.size(), 5u);
    EXPECT_EQ(m.input_points, 5u);
  }
}

TEST(Ingest, StlCornersAtOnePositionAreOneVertexAndOthersStayApart) {
  // Two facets sharing an edge, one corner written as -0 in one and 0 in the other; a
  // third facet whose corners differ from theirs in the last bit only.
  std::string b(80, ' ');
  put<std::uint32_t>(b, 3);
  const float next = std::nextafter(1.0f, 2.0f);
  const float facets[3][9] = {
      {0, 0, 0, 1, 0, 0, 1, 1, 0}, {-0.0f, 0, 0, 1, 1, 0, 0, 1, 0}, {next, 0, 0, next, 1, 0, 2, 0, 0}};
  for (const auto& f : facets) {
    for (int k = 0; k < 3; ++k) put<float>(b, 0.0f);
    for (const float x : f) put<float>(b, x);
    put<std::uint16_t>(b, 0);
  }
  const Mesh m = read_mesh(write_file("weld.stl", b));
  ASSERT_EQ(m.triangles.size(), 3u);
  EXPECT_EQ(m.vertices.size(), 4u + 3u);
  EXPECT_EQ(m.triangles[0][0], m.triangles[1][0]);  // -0 and 0
  EXPECT_EQ(m.triangles[0][2], m.triangles[1][1]);  // (1, 1, 0)
  for (const auto v : m.triangles[2]) EXPECT_GE(v, 4u);
}

TEST(Ingest, MillimetresAreScaledToMetres) {
  ReadOptions o;
  o.scale_to_m = 1e-3;
  expect_reference(read_mesh(write_file("e.ply", ascii_ply()), o), 1e-3f);
}

// A curved panel w x h (m) sampled `step` apart 0.9 m from the sensor, in units of `unit`
// metres, with `outliers` vertices thrown 50 m away.
Mesh grid_panel(double w, double h, double step, double unit, int outliers = 0) {
  Mesh m;
  const int nx = static_cast<int>(w / step) + 1, ny = static_cast<int>(h / step) + 1;
  for (int y = 0; y < ny; ++y)
    for (int x = 0; x < nx; ++x) {
      const double px = x * step - 0.5 * w, py = y * step - 0.5 * h;
      m.vertices.push_back((Eigen::Vector3d(px, py, 0.9 - 0.3 * px * px) / unit).cast<float>());
    }
  for (int k = 0; k < outliers; ++k)
    m.vertices[static_cast<std::size_t>(k) * 997].z() += static_cast<float>(50.0 / unit);
  for (int y = 0; y + 1 < ny; ++y)
    for (int x = 0; x + 1 < nx; ++x) {
      const auto i = static_cast<std::uint32_t>(y * nx + x), n = static_cast<std::uint32_t>(nx);
      m.triangles.push_back({i, i + n + 1, i + 1});
      m.triangles.push_back({i, i + n, i + n + 1});
    }
  return m;
}

TEST(Ingest, MillimetreScansAreToldFromMetreScans) {
  struct Case {
    const char* what;
    double w, h, step, unit;
    int outliers;
    bool mm;
  };
  for (const Case& c :
       {Case{"door, m", 1.0, 0.8, 0.002, 1.0, 0, false}, Case{"door, mm", 1.0, 0.8, 0.002, 1e-3, 0, true},
        Case{"coarse door (paper), m", 1.0, 0.8, 0.0045, 1.0, 0, false},
        Case{"roof, m, with outliers 50 m off", 2.0, 1.5, 0.005, 1.0, 40, false},
        Case{"20 mm patch, mm", 0.02, 0.02, 0.0001, 1e-3, 0, true},
        Case{"20 mm patch, m", 0.02, 0.02, 0.0001, 1.0, 0, false}}) {
    SCOPED_TRACE(c.what);
    const ScaleEvidence e = measure_scale(grid_panel(c.w, c.h, c.step, c.unit, c.outliers));
    EXPECT_NEAR(e.spacing, c.step / c.unit, 0.01 * c.step / c.unit);
    EXPECT_NEAR(e.extent, std::hypot(c.w, c.h) / c.unit, 0.1 * std::hypot(c.w, c.h) / c.unit);
    EXPECT_EQ(looks_like_millimetres(e), c.mm);
  }
}

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

TEST(Ingest, ObjWithPlainFacesAndAByteOrderMark) {
  // 'f 1 2 3', the commonest face, once failed as a "bad face corner".
  const std::string obj = "v 0 0 1\nv 1 0 1\nv 0 1 1\nv 1 1 1\nf 1 2 3\nf 2 4 3\n";
  const Mesh a = read_mesh(write_file("k0.obj", obj)),
             b = read_mesh(write_file("k1.obj", "\xEF\xBB\xBF" + obj));
  EXPECT_EQ(a.vertices, b.vertices);
  EXPECT_EQ(a.triangles, b.triangles);
  EXPECT_EQ(b.vertices.size(), 4u);
}

TEST(Ingest, ErrorsNameFileAndPosition) {
  auto message = [](const std::string& name, const std::string& bytes) {
    const std::string p = write_file(name, bytes);
    try {
      read_mesh(p);
    } catch (const IngestError& e) {
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
      EXPECT_NE(std::string(e.what()).find(p), std::string::npos) << e.what();
      return std::string(e.what());
    }
    ADD_FAILURE() << "no error for " << name;
    return std::string();
  };
  std::string bad = ascii_ply();
  bad.replace(bad.find("3 1 4 2"), 7, "3 1 9 2");
  EXPECT_NE(message("g.ply", bad).find("line 18: vertex index 9 out of range"), std::string::npos);
  std::string bad2 = ascii_ply();
  bad2.replace(bad2.find("1.000000 1.000000"), 8, "1.0x0000");
  EXPECT_NE(message("h.ply", bad2).find("line 14"), std::string::npos);
  EXPECT_NE(message("i.obj", "v 0 0 0\nv 1 0 0\nf 1 2 3\n").find("line 3"), std::string::npos);
  const std::string b = binary_ply(false, false, "uchar", "int");
  EXPECT_NE(message("j.ply", b.substr(0, b.size() - 5)).find("byte"), std::string::npos);
  EXPECT_NE(message("k.stl", "hello").find("byte 0"), std::string::npos);
  EXPECT_NE(message("l.ply", "").find("empty"), std::string::npos);
  // Found by the fuzzer: faces read against a first vertex list, then a shorter second one.
  std::string two_lists = ascii_ply();
  two_lists.replace(two_lists.find("element face"), 0,
                    "element vertex 1\nproperty float x\nproperty float y\nproperty float z\n");
  two_lists.replace(two_lists.find("4 0 1 2 3"), 0, "0 0 0\n");
  EXPECT_NE(message("m.ply", two_lists).find("line 9: a second 'vertex' element"), std::string::npos);
  EXPECT_THROW(read_mesh(temp_path("missing.ply")), IngestError);
}

// Property: any truncation or corruption of a valid file is either read or reported
// as an IngestError; it never crashes, hangs or returns out-of-range indices.
TEST(Ingest, TruncationAndCorruptionNeverCrash) {
  std::mt19937 rng(42);
  const std::vector<std::pair<std::string, std::string>> files = {
      {"p.ply", binary_ply(false, false, "uchar", "int")},
      {"q.ply", binary_ply(true, true, "int", "uint")},
      {"r.ply", ascii_ply()},
      {"s.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3 4\n"}};
  int errors = 0, reads = 0;
  for (const auto& [name, bytes] : files) {
    for (std::size_t n = 0; n < bytes.size(); ++n) {
      std::string cut = bytes.substr(0, n);
      std::string corrupt = bytes;
      for (int k = 0; k < 3; ++k) corrupt[rng() % corrupt.size()] = static_cast<char>(rng());
      for (const auto& variant : {cut, corrupt}) {
        try {
          const Mesh m = read_mesh(write_file(name, variant));
          for (const auto& t : m.triangles)
            for (auto i : t) ASSERT_LT(i, m.vertices.size());
          ++reads;
        } catch (const IngestError&) {
          ++errors;
        }
      }
    }
  }
  EXPECT_GT(errors, 100);
  EXPECT_GT(reads, 0);
}

TEST(Ingest, NonFiniteVerticesDropTheirFaces) {
  std::string s = ascii_ply();
  s.replace(s.find("2.000000 0.000000 1.000000"), 26, "nan 0 1");
  const Mesh m = read_mesh(write_file("t.ply", s));
  EXPECT_EQ(m.nonfinite_vertices, 1u);
  EXPECT_EQ(m.triangles.size(), 2u);
  EXPECT_EQ(m.dropped_faces, 1u);
}

TEST(Ingest, PlyWriterRoundTrips) {
  Mesh m = read_mesh(write_file("u.ply", ascii_ply()));
  const std::string out = temp_path("v.ply");
  write_ply(out, m, std::vector<std::array<std::uint8_t, 3>>(5, {1, 2, 3}));
  expect_reference(read_mesh(out));
  EXPECT_FALSE(std::filesystem::exists(out + ".tmp"));
}

}  // namespace
}  // namespace dentmark::ingest

namespace dentmark::ingest {
namespace {

// The common scanner layout (only triangles, one list property) takes a parallel path;
// it must read the same and reject the same.
std::string triangle_block_ply(int bad_index, const std::string& index_type = "uint") {
  std::string s =
      "ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
      "property float z\nelement face 3\nproperty list uchar " +
      index_type + " vertex_indices\nend_header\n";
  for (auto& v : kV)
    for (int a = 0; a < 3; ++a) put<float>(s, v[a]);
  for (auto t : {std::array<int, 3>{0, 1, 2}, {0, 2, 3}, {1, bad_index, 2}}) {
    put<std::uint8_t>(s, 3);
    for (int i : t) put<std::uint32_t>(s, static_cast<std::uint32_t>(i));
  }
  return s;
}

TEST(Ingest, BinaryTriangleBlockFastPath) {
  expect_reference(read_mesh(write_file("w.ply", triangle_block_ply(4))));
  const std::string bad = triangle_block_ply(5);
  // Third face's second corner: header, 5 x 12 vertex bytes, 2 x 13 face bytes, count, corner.
  const std::size_t at = bad.find("end_header\n") + 11 + 60 + 26 + 1 + 4;
  try {
    read_mesh(write_file("x.ply", bad));
    ADD_FAILURE() << "index 5 of 5 vertices accepted";
  } catch (const IngestError& e) {
    EXPECT_NE(std::string(e.what()).find("byte " + std::to_string(at) + ": vertex index 5 out of range"),
              std::string::npos)
        << e.what();
  }
  // Signed 32-bit indices take the same plain-load path: a negative one is rejected.
  expect_reference(read_mesh(write_file("y.ply", triangle_block_ply(4, "int"))));
  for (int negative : {-1, -2147483647 - 1}) {
    try {
      read_mesh(write_file("z.ply", triangle_block_ply(negative, "int")));
      ADD_FAILURE() << "index " << negative << " accepted";
    } catch (const IngestError& e) {
      // Any negative index is reported as -1 (the loader's "not a valid index").
      EXPECT_NE(std::string(e.what()).find("vertex index -1 out of range"), std::string::npos) << e.what();
    }
  }
}

void expect_reference(const MeshView& m, float scale = 1.0f) {
  ASSERT_EQ(m.vertex_count(), 5u);
  ASSERT_EQ(m.triangle_count(), 3u);
  for (std::size_t i = 0; i < 5; ++i)
    for (int a = 0; a < 3; ++a) EXPECT_FLOAT_EQ(m.vertex(i)[a], kV[i][a] * scale);
  EXPECT_EQ(m.triangle(0), (std::array<std::uint32_t, 3>{0, 1, 2}));
  EXPECT_EQ(m.triangle(1), (std::array<std::uint32_t, 3>{0, 2, 3}));
  EXPECT_EQ(m.triangle(2), (std::array<std::uint32_t, 3>{1, 4, 2}));
}

// A scanner-style PLY: a leading 'flag' before x, y, z, a trailing confidence, an extra
// element between the blocks, and triangle faces.
std::string scanner_ply(const std::string& index_type, float poison = 0.0f, int bad_index = 4) {
  std::string s =
      "ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty uchar flag\nproperty float x\n"
      "property float y\nproperty float z\nproperty float confidence\nelement camera 1\nproperty double "
      "f\nelement face 3\nproperty list uchar " +
      index_type + " vertex_indices\nend_header\n";
  for (auto& v : kV) {
    put<std::uint8_t>(s, 9);
    for (int a = 0; a < 3; ++a) put<float>(s, v[a] + (&v == &kV[3] && a == 2 ? poison : 0.0f));
    put<float>(s, 0.5f);
  }
  put<double>(s, 1200.0);
  for (auto t : {std::array<int, 3>{0, 1, 2}, {0, 2, 3}, {1, bad_index, 2}}) {
    put<std::uint8_t>(s, 3);
    for (int i : t) put<std::uint32_t>(s, static_cast<std::uint32_t>(i));
  }
  return s;
}

// The reference triangles as a soup (each with its own three corners) in the scanner's
// binary layout, or as ascii.
std::string soup_ply(bool binary) {
  const int tris[3][3] = {{0, 1, 2}, {0, 2, 3}, {1, 4, 2}};
  std::string s = std::string("ply\nformat ") + (binary ? "binary_little_endian" : "ascii") +
                  " 1.0\nelement vertex 9\nproperty float x\nproperty float y\nproperty float z\n"
                  "element face 3\nproperty list uchar int vertex_indices\nend_header\n";
  for (const auto& t : tris)
    for (const int i : t) {
      if (binary)
        for (int a = 0; a < 3; ++a) put<float>(s, kV[i][a]);
      else
        s +=
            std::to_string(kV[i][0]) + " " + std::to_string(kV[i][1]) + " " + std::to_string(kV[i][2]) + "\n";
    }
  for (int t = 0; t < 3; ++t) {
    if (binary) {
      put<std::uint8_t>(s, 3);
      for (int k = 0; k < 3; ++k) put<std::int32_t>(s, 3 * t + k);
    } else {
      s += "3 " + std::to_string(3 * t) + " " + std::to_string(3 * t + 1) + " " + std::to_string(3 * t + 2) +
           "\n";
    }
  }
  return s;
}

TEST(Scan, ATriangleSoupIsWeldedInEveryFormat) {
  // A PLY written from STL keeps every triangle's own corners: no two triangles share an
  // edge. Such a file is read (not used in place) and its coincident corners welded.
  for (const bool binary : {true, false}) {
    SCOPED_TRACE(binary);
    const Scan scan = open_scan(write_file("soup.ply", soup_ply(binary)));
    EXPECT_FALSE(scan.in_place);
    EXPECT_EQ(scan.input_points, 9u);  // as in the file
    ASSERT_EQ(scan.mesh.vertex_count(), 5u);
    ASSERT_EQ(scan.mesh.triangle_count(), 3u);
    const int tris[3][3] = {{0, 1, 2}, {0, 2, 3}, {1, 4, 2}};
    for (int t = 0; t < 3; ++t)
      for (int c = 0; c < 3; ++c)
        for (int a = 0; a < 3; ++a)
          EXPECT_FLOAT_EQ(scan.mesh.vertex(scan.mesh.triangle(t)[c])[a], kV[tris[t][c]][a]);
  }
}

TEST(Scan, ScannerLayoutIsUsedInPlace) {
  for (const std::string type : {"int", "uint"}) {
    const Scan scan = open_scan(write_file("s1.ply", scanner_ply(type)));
    EXPECT_TRUE(scan.in_place) << type;
    EXPECT_EQ(scan.input_points, 5u);
    expect_reference(scan.mesh);
  }
  ReadOptions mm;
  mm.scale_to_m = 1e-3;
  const Scan scaled = open_scan(write_file("s2.ply", triangle_block_ply(4)), mm);
  EXPECT_TRUE(scaled.in_place);
  expect_reference(scaled.mesh, 1e-3f);
  // The same bytes through the copying reader give the very same coordinates.
  const Mesh copy = read_mesh(write_file("s3.ply", triangle_block_ply(4)), mm);
  for (std::size_t i = 0; i < 5; ++i) EXPECT_EQ(scaled.mesh.vertex(i), copy.vertices[i]);
  // The check's bounding box is the vertices' own, scaled as they are.
  ASSERT_TRUE(scaled.mesh.has_bounds());
  Eigen::Vector3f lo = scaled.mesh.vertex(0), hi = lo;
  for (std::size_t i = 1; i < 5; ++i)
    lo = lo.cwiseMin(scaled.mesh.vertex(i)), hi = hi.cwiseMax(scaled.mesh.vertex(i));
  EXPECT_EQ(scaled.mesh.bounds_min(), lo);
  EXPECT_EQ(scaled.mesh.bounds_max(), hi);
}

TEST(Scan, AScanUsedInPlaceKnowsEachVertexBlocksBox) {
  // 700 vertices of a wavy sheet in mm: two whole blocks of 256 and a partial one. Each
  // block's box is its vertices' own, scaled as they are; a Mesh's view has none.
  Mesh m;
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> jitter(-0.3f, 0.3f);
  for (int i = 0; i < 700; ++i)
    m.vertices.emplace_back(static_cast<float>(i % 35) + jitter(rng),
                            static_cast<float>(i / 35) + jitter(rng),
                            5.0f * std::sin(0.1f * static_cast<float>(i)));
  for (std::uint32_t r = 0; r + 1 < 20; ++r)
    for (std::uint32_t c = 0; c + 1 < 35; ++c) {
      const std::uint32_t a = r * 35 + c;
      m.triangles.push_back({a, a + 1, a + 36});
      m.triangles.push_back({a, a + 36, a + 35});
    }
  const std::string path = temp_path("blocks.ply");
  write_ply(path, m);
  ReadOptions mm;
  mm.scale_to_m = 1e-3;
  const Scan scan = open_scan(path, mm);
  ASSERT_TRUE(scan.in_place);
  const VertexBlocks* blocks = scan.mesh.vertex_blocks();
  ASSERT_NE(blocks, nullptr);
  ASSERT_EQ(blocks->lo.size(), 3u);
  ASSERT_EQ(blocks->hi.size(), 3u);
  for (std::size_t b = 0; b < 3; ++b) {
    SCOPED_TRACE(b);
    Eigen::Vector3f lo = scan.mesh.vertex(b * VertexBlocks::kSize), hi = lo;
    for (std::size_t i = b * VertexBlocks::kSize;
         i < std::min<std::size_t>(700, (b + 1) * VertexBlocks::kSize); ++i)
      lo = lo.cwiseMin(scan.mesh.vertex(i)), hi = hi.cwiseMax(scan.mesh.vertex(i));
    EXPECT_EQ(blocks->lo[b], lo);
    EXPECT_EQ(blocks->hi[b], hi);
  }
  EXPECT_EQ(MeshView(m).vertex_blocks(), nullptr);
}

TEST(Scan, AnyOtherLayoutIsReadAndGivesTheSameMesh) {
  // Polygons, big endian, doubles, ascii, 16-bit indices: read into a Mesh, same result.
  for (const auto& [name, bytes] :
       std::vector<std::pair<std::string, std::string>>{{"o1.ply", binary_ply(false, false, "uchar", "int")},
                                                        {"o2.ply", binary_ply(true, false, "uchar", "int")},
                                                        {"o3.ply", binary_ply(false, true, "int", "uint")},
                                                        {"o4.ply", ascii_ply()}}) {
    const Scan scan = open_scan(write_file(name, bytes));
    EXPECT_FALSE(scan.in_place) << name;
    expect_reference(scan.mesh);
  }
  // A scan that could be used in place but holds a NaN: read, the NaN's faces dropped.
  const Scan nan = open_scan(write_file("o5.ply", scanner_ply("uint", std::nanf(""))));
  EXPECT_FALSE(nan.in_place);
  EXPECT_EQ(nan.nonfinite_vertices, 1u);
  EXPECT_EQ(nan.dropped_faces, 1u);
  EXPECT_EQ(nan.mesh.triangle_count(), 2u);
}

TEST(Scan, BadIndexInTheScannerLayoutIsReportedAsByTheReader) {
  const std::string path = write_file("b1.ply", scanner_ply("uint", 0.0f, 5));
  std::string from_reader, from_scan;
  try {
    read_mesh(path);
  } catch (const IngestError& e) {
    from_reader = e.what();
  }
  try {
    open_scan(path);
  } catch (const IngestError& e) {
    from_scan = e.what();
  }
  EXPECT_NE(from_reader.find("vertex index 5 out of range"), std::string::npos) << from_reader;
  EXPECT_EQ(from_scan, from_reader);
  // Truncated: one byte short of the last face. Not in place, and reported.
  const std::string full = scanner_ply("uint");
  EXPECT_THROW(open_scan(write_file("b2.ply", full.substr(0, full.size() - 1))), IngestError);
}

TEST(Scan, RandomMeshesReadTheSameInPlaceAndCopied) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    Mesh m;
    // (At least half as many triangles as vertices: a soup is welded, not used in place.)
    const int nv = 3 + static_cast<int>(rng() % 200), nt = 1 + nv / 2 + static_cast<int>(rng() % 400);
    std::uniform_real_distribution<float> u(-2.0f, 2.0f);
    for (int i = 0; i < nv; ++i) m.vertices.emplace_back(u(rng), u(rng), u(rng));
    for (int t = 0; t < nt; ++t)
      m.triangles.push_back({static_cast<std::uint32_t>(rng() % nv), static_cast<std::uint32_t>(rng() % nv),
                             static_cast<std::uint32_t>(rng() % nv)});
    const std::string path = temp_path("r.ply");
    std::vector<std::array<std::uint8_t, 3>> colours;
    if (trial % 2) colours.assign(m.vertices.size(), {1, 2, 3});  // stride 15
    write_ply(path, m, colours);
    const Scan scan = open_scan(path);
    ASSERT_TRUE(scan.in_place);
    ASSERT_EQ(scan.mesh.vertex_count(), m.vertices.size());
    ASSERT_EQ(scan.mesh.triangle_count(), m.triangles.size());
    for (std::size_t i = 0; i < m.vertices.size(); ++i) ASSERT_EQ(scan.mesh.vertex(i), m.vertices[i]);
    for (std::size_t t = 0; t < m.triangles.size(); ++t) ASSERT_EQ(scan.mesh.triangle(t), m.triangles[t]);
  }
}

TEST(Ingest, HeaderCountsBeyondTheFileAreReportedNotAllocated) {
  // 10^12 vertices or faces claimed by a few hundred bytes: an error naming the file and
  // where it ends, never std::bad_alloc.
  const std::string head = "ply\nformat ascii 1.0\nelement vertex ";
  const std::string props = "\nproperty float x\nproperty float y\nproperty float z\nelement face ";
  const std::string tail =
      "\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  for (const auto& [nv, nf] :
       {std::pair<const char*, const char*>{"999999999999", "1"}, {"3", "999999999999"}}) {
    try {
      read_mesh(write_file("huge.ply", head + nv + props + nf + tail));
      ADD_FAILURE() << nv << " / " << nf << " accepted";
    } catch (const IngestError& e) {
      EXPECT_NE(std::string(e.what()).find("huge.ply: line "), std::string::npos) << e.what();
    }
  }
  std::string binary = "ply\nformat binary_little_endian 1.0\nelement vertex 3" + props + "999999999999" +
                       "\nproperty list uchar int vertex_indices\nproperty uchar flags\nend_header\n";
  for (int i = 0; i < 9; ++i) put<float>(binary, static_cast<float>(i));
  EXPECT_THROW(read_mesh(write_file("huge_binary.ply", binary)), IngestError);
}

}  // namespace
}  // namespace dentmark::ingest

namespace dentmark::ingest {
namespace {

// The IngestError message for reading `bytes` as file `name` (read_mesh, or open_scan
// when `scan`); "" and a test failure when the file is accepted.
std::string ingest_error(const std::string& name, const std::string& bytes, bool scan = false) {
  const std::string p = write_file(name, bytes);
  try {
    if (scan)
      open_scan(p);
    else
      read_mesh(p);
  } catch (const IngestError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    EXPECT_EQ(what.rfind(p + ": ", 0), 0u) << what;
    return what;
  }
  ADD_FAILURE() << name << " accepted";
  return "";
}

std::string with_header_line(std::string ply, const std::string& from, const std::string& to) {
  ply.replace(ply.find(from), from.size(), to);
  return ply;
}

TEST(Ingest, PlyCountsThatDoNotMatchTheBodyAreReported) {
  // Binary: the declared elements must end where the file ends. Each case once read a
  // mesh (a face short, or the garbage ignored) and exited 0.
  const std::string good = triangle_block_ply(4);
  const std::size_t body = good.find("end_header\n") + 11, faces = body + 60;
  std::string count_byte_2 = good;
  count_byte_2[faces + 26] = 2;  // the last face: 2 corners, 4 bytes left over
  const std::vector<std::tuple<std::string, std::string, std::size_t, std::string>> binary = {
      {"nf_minus1", with_header_line(good, "element face 3", "element face 2"), faces + 26, "13 bytes after"},
      {"nf_minus2", with_header_line(good, "element face 3", "element face 1"), faces + 13, "26 bytes after"},
      {"trailing", good + std::string(7, '\0'), good.size(), "7 bytes after"},
      {"nv_plus1", with_header_line(good, "element vertex 5", "element vertex 6"), faces + 12,
       "face 0 has no corners"},
      {"count_byte_2_last", count_byte_2, faces + 26 + 9, "4 bytes after"}};
  for (const auto& [name, bytes, at, what] : binary) {
    SCOPED_TRACE(name);
    const std::string e = ingest_error("cm_" + name + ".ply", bytes);
    EXPECT_NE(e.find(": byte " + std::to_string(at) + ": " + what), std::string::npos) << e;
    EXPECT_NE(e.find("the header's element counts do not match the body"), std::string::npos) << e;
    // The in-place path of open_scan reports it the same way.
    EXPECT_EQ(ingest_error("cm_" + name + ".ply", bytes, true), e);
  }
  // Big endian, polygons and a per-face property: one face fewer than the body holds.
  const std::string be = binary_ply(true, false, "uchar", "int");
  const std::string e = ingest_error("cm_be.ply", with_header_line(be, "element face 2", "element face 1"));
  EXPECT_NE(e.find(": byte " + std::to_string(be.size() - 14) + ": 14 bytes after the last element 'face'"),
            std::string::npos)
      << e;
  // Ascii: text after the last element is reported at its line; blank lines are not.
  EXPECT_NO_THROW(read_mesh(write_file("cm_blank.ply", ascii_ply() + "\n  \r\n\n")));
  const std::string a =
      ingest_error("cm_ascii.ply", with_header_line(ascii_ply(), "element face 2", "element face 1"));
  EXPECT_NE(a.find(": line 18: text after the last element 'face': the header's element counts do not match"),
            std::string::npos)
      << a;
}

TEST(Ingest, AsciiPlyListsOfOtherTypesAreReadByTheirType) {
  // MeshLab writes per-face texture coordinates as 'property list uchar float texcoord':
  // once read as integers ("expected an integer for vertex index").
  std::string s =
      with_header_line(ascii_ply(), "property list uchar int vertex_indices\n",
                       "property list uchar int vertex_indices\nproperty list uchar float texcoord\n");
  s = with_header_line(s, "4 0 1 2 3\n", "4 0 1 2 3 8 0.5 0.25 1e-3 -0.125 0.75 1.0 0 1\n");
  s = with_header_line(s, "3 1 4 2\n", "3 1 4 2 6 0.1 0.2 0.3 0.4 0.5 0.6\n");
  expect_reference(read_mesh(write_file("tc.ply", s)));
  // A float-typed index list is read as numbers too; a fraction is no index.
  std::string f =
      with_header_line(ascii_ply(), "list uchar int vertex_indices", "list uchar float vertex_indices");
  expect_reference(read_mesh(write_file("tf.ply", f)));
  const std::string e = ingest_error("tg.ply", with_header_line(f, "3 1 4 2", "3 1 4.5 2"));
  EXPECT_NE(e.find(": line 18: expected a whole number for vertex index"), std::string::npos) << e;
}

TEST(Ingest, EndHeaderInsideACommentDoesNotEndTheHeader) {
  // Once read the comment as the header's end: the binary body was taken from the wrong
  // byte ("fewer than 3 usable points").
  for (const std::string comment : {"comment written by X: header ends at end_header\n",
                                    "comment end_header here\n", "obj_info end_header\n"}) {
    SCOPED_TRACE(comment);
    const std::string bin =
        with_header_line(triangle_block_ply(4), "element vertex", comment + "element vertex");
    expect_reference(read_mesh(write_file("eh1.ply", bin)));
    const Scan scan = open_scan(write_file("eh2.ply", bin));
    EXPECT_TRUE(scan.in_place);
    expect_reference(scan.mesh);
    expect_reference(
        read_mesh(write_file("eh3.ply", with_header_line(ascii_ply(), "comment test\n", comment))));
  }
  // The line itself may carry blanks and a '\r'.
  expect_reference(read_mesh(
      write_file("eh4.ply", with_header_line(triangle_block_ply(4), "end_header\n", " end_header \r\n"))));
}

TEST(Ingest, PlyHeaderErrorsNameTheHeaderLine) {
  // Once "vertex element lacks x, y or z", with no position.
  const std::string ascii =
      ingest_error("hl1.ply", with_header_line(ascii_ply(), "property float z", "property float w"));
  EXPECT_NE(ascii.find(": line 4: element 'vertex' has no property 'z'"), std::string::npos) << ascii;
  const std::string bin = triangle_block_ply(4);
  const std::string e =
      ingest_error("hl2.ply", with_header_line(bin, "property float x", "property float u"));
  EXPECT_NE(e.find(": line 3: element 'vertex' has no property 'x'"), std::string::npos) << e;
  EXPECT_EQ(ingest_error("hl2.ply", with_header_line(bin, "property float x", "property float u"), true), e);
  const std::string l = ingest_error(
      "hl3.ply",
      with_header_line(bin, "property float z\n", "property float z\nproperty list uchar int n\n"));
  EXPECT_NE(l.find(": line 3: a binary 'vertex' element with list properties is not supported"),
            std::string::npos)
      << l;
}

// The reference faces as ascii STL, keywords written by `k`, each line led by `indent`.
std::string ascii_stl(
    const std::function<std::string(std::string)>& k = [](std::string s) { return s; },
    const std::string& indent = "") {
  const int tris[3][3] = {{0, 1, 2}, {0, 2, 3}, {1, 4, 2}};
  std::string a = k("solid") + " t\n";
  for (auto& t : tris) {
    a += indent + k("facet normal") + " 0 0 1\n" + indent + k("outer loop") + "\n";
    for (int i : t)
      a += indent + k("vertex") + " " + std::to_string(kV[i][0]) + " " + std::to_string(kV[i][1]) + " " +
           std::to_string(kV[i][2]) + "\n";
    a += indent + k("endloop") + "\n" + indent + k("endfacet") + "\n";
  }
  return a + k("endsolid") + " t\n";
}

void expect_stl_reference(const Mesh& m) {
  const int tris[3][3] = {{0, 1, 2}, {0, 2, 3}, {1, 4, 2}};
  ASSERT_EQ(m.triangles.size(), 3u);
  for (int t = 0; t < 3; ++t)
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < 3; ++k) EXPECT_FLOAT_EQ(m.vertices[m.triangles[t][c]][k], kV[tris[t][c]][k]);
}

TEST(Ingest, AsciiStlKeywordsInAnyCaseAfterBlanks) {
  const auto upper = [](std::string s) {
    for (auto& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    return s;
  };
  const auto mixed = [](std::string s) {
    if (!s.empty()) s[0] = static_cast<char>(std::toupper(static_cast<unsigned char>(s[0])));
    return s;
  };
  expect_stl_reference(read_mesh(write_file("su1.stl", ascii_stl(upper))));
  expect_stl_reference(read_mesh(write_file("su2.stl", ascii_stl(mixed, "\t "))));
  expect_stl_reference(read_mesh(write_file("su3.stl", "  \r\n\n\t" + ascii_stl())));
  expect_stl_reference(read_mesh(write_file("su4.stl", "\xEF\xBB\xBF" + ascii_stl())));
  // Neither binary of the right size nor ascii: said so, at the byte that is neither.
  const std::string e = ingest_error("su5.stl", "\n  hello world\n");
  EXPECT_NE(e.find(": byte 3: neither a binary STL of matching size"), std::string::npos) << e;
  EXPECT_NE(e.find("nor ASCII STL"), std::string::npos) << e;
  // A binary STL whose header starts with "solid" (SolidWorks) but whose count is wrong:
  // the first non-text byte is named, not "unexpected '<raw bytes>'" on line 2.
  std::string b = "solid part exported by a CAD tool";
  b.resize(80, ' ');
  put<std::uint32_t>(b, 2);
  for (int i = 0; i < 12; ++i) put<float>(b, 0.25f);
  b += std::string(2, '\0');  // one facet of the two
  const std::string s = ingest_error("su6.stl", b);
  EXPECT_NE(
      s.find(": byte 80: neither a binary STL of matching size (its header's 2 facets need 184 bytes, the "
             "file has 134) nor ASCII STL"),
      std::string::npos)
      << s;
}

TEST(Ingest, AsciiStlStructureIsChecked) {
  const std::string good = ascii_stl();
  // Several solids in one file stay valid.
  const std::size_t second = good.find("endfacet\n") + 9;  // where the second facet starts
  std::string solids = good;
  solids.insert(second, "endsolid t\nsolid u\n");
  expect_stl_reference(read_mesh(write_file("st1.stl", solids)));
  // A missing 'endloop' once dropped the facet silently; a facet has exactly 3 vertices;
  // a file cut between facets (no 'endsolid') once read as a smaller mesh.
  std::string no_endloop = good;
  no_endloop.erase(no_endloop.find("endloop\n"), 8);
  std::string two_vertices = good;
  two_vertices.erase(two_vertices.find("vertex"),
                     two_vertices.find('\n', two_vertices.find("vertex")) - two_vertices.find("vertex") + 1);
  std::string four_vertices = good;
  four_vertices.insert(four_vertices.find("endloop"), "vertex 0 0 0\n");
  const std::string cut = good.substr(0, second);
  for (const auto& [name, bytes, where] : std::vector<std::tuple<std::string, std::string, std::string>>{
           {"st2.stl", no_endloop, ": line 7: 'endfacet' where 'vertex' or 'endloop' belongs"},
           {"st3.stl", two_vertices, ": line 6: facet loop with 2 vertices (a facet has 3)"},
           {"st4.stl", four_vertices, ": line 7: a fourth 'vertex' in a facet (a facet has 3)"},
           {"st5.stl", cut,
            ": line 8: the file ends here with no 'endsolid' after the last facet: is it cut short?"},
           {"st6.stl", cut.substr(0, cut.size() - 9), ": line 7: the file ends inside a facet"}}) {
    SCOPED_TRACE(name);
    const std::string e = ingest_error(name, bytes);
    EXPECT_NE(e.find(where), std::string::npos) << e;
  }
}

TEST(Ingest, ObjFaceWithFewerThanThreeCornersIsAnError) {
  // A file cut inside its last face ('f 12//12 1//1') once read as if that face were not
  // there.
  const std::string v = "v 0 0 1\nv 1 0 1\nv 0 1 1\nv 1 1 1\nf 1//1 2//1 3//1\n";
  for (const std::string last : {"f 2//1 4//1", "f 2//1 4//1\n", "f 2 4\n", "f 2\n", "f\n"}) {
    SCOPED_TRACE(last);
    const std::string e = ingest_error("of.obj", v + last);
    EXPECT_NE(e.find(": line 6: face with "), std::string::npos) << e;
    EXPECT_NE(e.find("corners (a face needs at least 3)"), std::string::npos) << e;
  }
  expect_reference(read_mesh(write_file("og.obj",
                                        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 1\n"
                                        "f 1 2 3 4\nf 2 5 3\nl 1 2\np 3\n")));
}

// The variants tools write: PLY faces named 'vertex_index' (older exporters), double
// coordinates, normals and colours before and after x y z, 'comment' and 'obj_info',
// either byte order; OBJ vertices with colours, 'v/vt/vn' corners, negative indices.
TEST(Ingest, PlyAndObjVariantsAsToolsWriteThem) {
  for (const bool big : {false, true})
    for (const bool ascii : {false, true}) {
      SCOPED_TRACE(std::to_string(big) + std::to_string(ascii));
      std::string s =
          std::string("ply\nformat ") +
          (ascii ? "ascii"
           : big ? "binary_big_endian"
                 : "binary_little_endian") +
          " 1.0\ncomment made by a tool\nobj_info num_cols 2\nelement vertex 5\n"
          "property float nx\nproperty double x\nproperty double y\nproperty double z\n"
          "property float ny\nproperty float nz\nproperty uchar red\nproperty uchar green\n"
          "property uchar blue\nelement face 2\nproperty list uchar int vertex_index\nend_header\n";
      for (auto& v : kV) {
        if (ascii) {
          s += "0.5 " + std::to_string(v[0]) + " " + std::to_string(v[1]) + " " + std::to_string(v[2]) +
               " 0.5 0.7 255 128 0\n";
          continue;
        }
        put<float>(s, 0.5f, big);
        for (int a = 0; a < 3; ++a) put<double>(s, v[a], big);
        put<float>(s, 0.5f, big), put<float>(s, 0.7f, big);
        s += "\xff\x80";
        s += '\0';
      }
      if (ascii) {
        s += "4 0 1 2 3\n3 1 4 2\n";
      } else {
        put<std::uint8_t>(s, 4);
        for (int i : {0, 1, 2, 3}) put<std::int32_t>(s, i, big);
        put<std::uint8_t>(s, 3);
        for (int i : {1, 4, 2}) put<std::int32_t>(s, i, big);
      }
      expect_reference(read_mesh(write_file("variant.ply", s)));
    }
  std::string obj = "mtllib door.mtl\no door\n";
  for (auto& v : kV)
    obj += "v " + std::to_string(v[0]) + " " + std::to_string(v[1]) + " " + std::to_string(v[2]) +
           " 0.6 0.6 0.65\n";
  obj +=
      "vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\nusemtl paint\ns 1\nf 1/1/1 2/2/1 3/3/1 -2/1/1\nf -4/1/1 -1/2/1 "
      "-3/3/1\n";
  expect_reference(read_mesh(write_file("variant.obj", obj)));
}

}  // namespace
}  // namespace dentmark::ingest
