// Ingest: scans used in place (open_scan): the scanner layout read without a copy, any other layout
// read and welded, and both give the same mesh.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "dentmark/common/ingest/mesh_writer.h"
#include "dentmark/host/ingest/read_mesh.h"
#include "dentmark/host/ingest/units.h"
#include "ingest_files.h"

namespace dentmark::ingest {
namespace {

using namespace testing;

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

}  // namespace
}  // namespace dentmark::ingest
