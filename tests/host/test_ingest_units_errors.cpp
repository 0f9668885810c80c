// Ingest: units and malformed files: millimetre scans told from metre scans and scaled; errors
// name the file and position, truncation and corruption never crash, non-finite
// vertices drop their faces.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "dentmark/host/ingest/read_mesh.h"
#include "dentmark/host/ingest/units.h"
#include "ingest_files.h"

namespace dentmark::ingest {
namespace {

using namespace testing;

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

}  // namespace
}  // namespace dentmark::ingest
