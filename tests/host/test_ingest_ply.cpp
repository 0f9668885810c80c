// Ingest: PLY: ascii and binary in every byte order and type, the scanners' triangle block, header
// and count errors that name the line or byte, the writer.

#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <tuple>
#include <vector>

#include "dentmark/common/ingest/mesh_writer.h"
#include "dentmark/host/ingest/read_mesh.h"
#include "ingest_files.h"

namespace dentmark::ingest {
namespace {

using namespace testing;

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

TEST(Ingest, PlyWriterRoundTrips) {
  Mesh m = read_mesh(write_file("u.ply", ascii_ply()));
  const std::string out = temp_path("v.ply");
  write_ply(out, m, std::vector<std::array<std::uint8_t, 3>>(5, {1, 2, 3}));
  expect_reference(read_mesh(out));
  EXPECT_FALSE(std::filesystem::exists(out + ".tmp"));
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

}  // namespace
}  // namespace dentmark::ingest
