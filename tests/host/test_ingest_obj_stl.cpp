// Ingest: OBJ and STL: polygons, textures, negative indices, ascii and binary STL welded, keywords
// in any case, structure errors; PLY and OBJ as other tools write them.

#include <gtest/gtest.h>

#include <cctype>
#include <cstdint>
#include <functional>
#include <string>
#include <tuple>
#include <vector>

#include "dentmark/host/ingest/read_mesh.h"
#include "ingest_files.h"

namespace dentmark::ingest {
namespace {

using namespace testing;

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

TEST(Ingest, ObjWithPlainFacesAndAByteOrderMark) {
  // 'f 1 2 3', the commonest face, once failed as a "bad face corner".
  const std::string obj = "v 0 0 1\nv 1 0 1\nv 0 1 1\nv 1 1 1\nf 1 2 3\nf 2 4 3\n";
  const Mesh a = read_mesh(write_file("k0.obj", obj)),
             b = read_mesh(write_file("k1.obj", "\xEF\xBB\xBF" + obj));
  EXPECT_EQ(a.vertices, b.vertices);
  EXPECT_EQ(a.triangles, b.triangles);
  EXPECT_EQ(b.vertices.size(), 4u);
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
