// PCD (PCL's format): ascii, binary and binary_compressed give the same points, fields in
// any order with any SIZE, TYPE and COUNT; an organised cloud keeps its holes; malformed
// files give one-line errors naming the file, the line or byte and the field; an unknown
// format is named as unknown. (Files written by PCL and Open3D themselves:
// tests/host/real_tools.)
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <tuple>
#include <vector>

#include "../../common/ingest/lzf.h"
#include "dentmark/common/ingest/detail/readers.h"
#include "dentmark/host/ingest/read_mesh.h"

namespace dentmark::ingest {
namespace {

std::string write_file(const std::string& name, const std::string& bytes) {
  static const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("dentmark_pcd_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string p = (dir / name).string();
  std::ofstream(p, std::ios::binary) << bytes;
  return p;
}

std::string read_error(const std::string& name, const std::string& bytes) {
  try {
    read_mesh(write_file(name, bytes));
  } catch (const IngestError& e) {
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    return e.what();
  }
  ADD_FAILURE() << name << " was read";
  return {};
}

template <typename T>
void put(std::string& s, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  s.append(b, sizeof(T));
}

// LZF of `raw` as literal runs only (valid LZF, if not small).
std::string lzf_literals(const std::string& raw) {
  std::string out;
  for (std::size_t i = 0; i < raw.size(); i += 32) {
    const std::size_t n = std::min<std::size_t>(32, raw.size() - i);
    out += static_cast<char>(n - 1);
    out += raw.substr(i, n);
  }
  return out;
}

const float kP[4][3] = {{0.1f, 0.2f, 1.0f}, {-0.25f, 0.5f, 1.5f}, {3.0f, -2.0f, 0.75f}, {0.0f, 0.0f, 2.0f}};

// The fields of a PCL cloud with normals and colour, x y z out of order and of three
// different types, a multi-valued field and padding between.
const char* const kFields =
    "FIELDS normal_x rgb z _ x y fpfh curvature\n"
    "SIZE 4 4 8 1 4 2 4 4\n"
    "TYPE F U F U F I F F\n"
    "COUNT 1 1 1 3 1 1 2 1\n";
// y is stored as a 16-bit integer: the points' y values are whole numbers of 1/4.
constexpr double kYScale = 4.0;

std::string header(const std::string& data, int width = 4, int height = 1) {
  return "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n" + std::string(kFields) + "WIDTH " +
         std::to_string(width) + "\nHEIGHT " + std::to_string(height) + "\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " +
         std::to_string(width * height) + "\nDATA " + data + "\n";
}

// The records as binary PCD stores them (point by point) or as binary_compressed
// decompresses to (field by field).
std::string records(bool field_major) {
  std::vector<std::string> field(8);
  for (const auto& p : kP) {
    put<float>(field[0], 0.5f);
    put<std::uint32_t>(field[1], 0x00ff8000u);
    put<double>(field[2], p[2]);
    field[3] += std::string(3, '\x7f');
    put<float>(field[4], p[0]);
    put<std::int16_t>(field[5], static_cast<std::int16_t>(std::lround(p[1] * kYScale)));
    put<float>(field[6], 1.0f), put<float>(field[6], 2.0f);
    put<float>(field[7], 0.01f);
  }
  std::string out;
  if (field_major) {
    for (const auto& f : field) out += f;
    return out;
  }
  const std::size_t sizes[8] = {4, 4, 8, 3, 4, 2, 8, 4};
  for (std::size_t i = 0; i < 4; ++i)
    for (std::size_t f = 0; f < 8; ++f) out += field[f].substr(i * sizes[f], sizes[f]);
  return out;
}

std::string ascii_pcd() {
  std::string s = header("ascii");
  for (const auto& p : kP)
    s += "0.5 16744448 " + std::to_string(p[2]) + " 127 127 127 " + std::to_string(p[0]) + " " +
         std::to_string(std::lround(p[1] * kYScale)) + " 1 2 0.01\n";
  return s;
}

std::string binary_pcd() {
  return header("binary") + records(false);
}

std::string compressed_pcd() {
  const std::string raw = records(true), packed = lzf_literals(raw);
  std::string s = header("binary_compressed");
  put<std::uint32_t>(s, static_cast<std::uint32_t>(packed.size()));
  put<std::uint32_t>(s, static_cast<std::uint32_t>(raw.size()));
  return s + packed;
}

void expect_points(const Mesh& m) {
  ASSERT_EQ(m.vertices.size(), 4u);
  for (int i = 0; i < 4; ++i) {
    EXPECT_FLOAT_EQ(m.vertices[i].x(), kP[i][0]) << i;
    EXPECT_FLOAT_EQ(m.vertices[i].y(), static_cast<float>(std::lround(kP[i][1] * kYScale))) << i;
    EXPECT_FLOAT_EQ(m.vertices[i].z(), kP[i][2]) << i;
  }
  EXPECT_TRUE(m.triangles.empty());
}

TEST(ReadPcd, EveryEncodingGivesTheSamePoints) {
  expect_points(detail::read_pcd("a.pcd", ascii_pcd()));
  expect_points(detail::read_pcd("b.pcd", binary_pcd()));
  expect_points(detail::read_pcd("c.pcd", compressed_pcd()));
  // PCL pads binary files to a whole memory page.
  expect_points(detail::read_pcd("b4k.pcd", binary_pcd() + std::string(4096 - binary_pcd().size(), '\0')));
  expect_points(detail::read_pcd("c4k.pcd", compressed_pcd() + std::string(100, '\0')));
  // Windows line ends, comments and blank lines in the header; v0.5's COLUMNS.
  std::string crlf;
  for (char c : ascii_pcd()) crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
  expect_points(detail::read_pcd("d.pcd", crlf));
  std::string old = ascii_pcd();
  old.replace(old.find("FIELDS"), 6, "# made by hand\n\nCOLUMNS");
  expect_points(detail::read_pcd("e.pcd", old));
}

TEST(ReadPcd, LzfBackReferencesOverlap) {
  // "abc", then 9 bytes from 3 back (they overlap what they write): "abcabcabcabc".
  const std::string in = std::string(
                             "\x02"
                             "abc") +
                         std::string("\xe0\x00\x02", 3);
  std::string out(12, '\0');
  ASSERT_FALSE(detail::lzf_decompress(in, out));
  EXPECT_EQ(out, "abcabcabcabc");
  std::string short_out(11, '\0');
  const auto e = detail::lzf_decompress(in, short_out);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->offset, 4u);
  std::string long_out(13, '\0');
  ASSERT_TRUE(detail::lzf_decompress(in, long_out));
  // A reference before the output's start; a literal run past the input's end.
  std::string o3(6, '\0');
  EXPECT_TRUE(detail::lzf_decompress(std::string("\x00"
                                                 "a\x20\x05",
                                                 4),
                                     o3));
  EXPECT_TRUE(detail::lzf_decompress(std::string("\x05"
                                                 "ab",
                                                 3),
                                     o3));
}

TEST(ReadPcd, AnOrganisedCloudKeepsItsHolesAndIsMeshed) {
  // A 40 x 30 pixel view of a plane 1 m away, with a 5 x 5 hole of NaN points.
  const int w = 40, h = 30;
  std::string s =
      "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 40\nHEIGHT 30\n"
      "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 1200\nDATA binary\n";
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const bool hole = r >= 10 && r < 15 && c >= 20 && c < 25;
      put<float>(s, hole ? nan : 0.002f * static_cast<float>(c - w / 2));
      put<float>(s, hole ? nan : 0.002f * static_cast<float>(r - h / 2));
      put<float>(s, hole ? nan : 1.0f);
    }
  const Mesh m = read_mesh(write_file("organised.pcd", s));
  EXPECT_EQ(m.input_points, 1200u);
  EXPECT_EQ(m.nonfinite_vertices, 25u);
  EXPECT_TRUE(m.from_point_cloud);
  // A grid of 39 x 29 cells, two triangles each, less those that touch the hole.
  EXPECT_GT(m.triangles.size(), 2u * 39 * 29 - 2 * 6 * 6 - 40);
  EXPECT_LE(m.triangles.size(), 2u * 39 * 29);
  for (const auto& t : m.triangles)
    for (auto i : t) EXPECT_TRUE(m.vertices[i].allFinite());
}

TEST(ReadPcd, ErrorsNameLineOrByteAndField) {
  const std::string a = ascii_pcd(), b = binary_pcd(), c = compressed_pcd();
  const auto edit = [](std::string s, const std::string& from, const std::string& to) {
    return s.replace(s.find(from), from.size(), to);
  };
  const std::size_t stream = c.find("DATA binary_compressed\n") + 23 + 8;
  for (const auto& [name, bytes, where] : std::vector<std::tuple<std::string, std::string, std::string>>{
           {"e1.pcd", edit(a, "SIZE 4 4 8 1", "SIZE 4 4 8"), "line 4: 'SIZE' has 7 values for 8 fields"},
           {"e2.pcd", edit(a, "TYPE F U F U", "TYPE F U F Q"), "line 5: field '_': TYPE 'Q' (I, U or F)"},
           {"e3.pcd", edit(a, "SIZE 4 4 8", "SIZE 4 4 2"), "line 11: field 'z': TYPE F with SIZE 2 (4 or 8)"},
           {"e4.pcd", edit(a, "COUNT 1 1 1 3", "COUNT 1 1 1 0"), "line 6: field '_': COUNT '0' (1 to 65536)"},
           {"e5.pcd", edit(a, "POINTS 4", "POINTS 5"), "line 11: POINTS 5 is not WIDTH x HEIGHT = 4 x 1"},
           {"e6.pcd", edit(a, "FIELDS normal_x rgb z", "FIELDS normal_x rgb w"),
            "line 11: no field 'z' in FIELDS"},
           {"e7.pcd", edit(a, "DATA ascii", "DATA zip"),
            "line 11: DATA 'zip' (ascii, binary or binary_compressed)"},
           {"e8.pcd", edit(a, "VIEWPOINT", "VIEWPIONT"), "line 9: unknown PCD header keyword 'VIEWPIONT'"},
           {"e9.pcd", edit(a, " 1 2 0.01\n", " 1 2\n"), "line 12: point 0 ends before field 'curvature'"},
           {"e10.pcd", edit(a, " 1 2 0.01\n", " 1 2 0.01 9\n"),
            "line 12: extra values after point 0's last field"},
           {"e11.pcd", edit(a, "127 127 127 0.1", "127 127 127 x"), "line 12: expected a number for x"},
           {"e12.pcd", a.substr(0, a.rfind("0.5 ")), "line 15: file ends after 3 of the header's 4 points"},
           {"e13.pcd", b.substr(0, b.size() - 1),
            "byte " + std::to_string(b.size() - 1) +
                ": 4 points of 37 bytes need 148 bytes, the file has 147"},

           {"e15.pcd", c.substr(0, stream + 3), "byte " + std::to_string(stream - 8) + ": compressed size"},
           {"e16.pcd", c.substr(0, stream - 5),
            "byte " + std::to_string(stream - 8) + ": file ends before binary_compressed's two sizes"},
           {"e17.pcd", c.substr(0, stream) + std::string("\x20") + c.substr(stream + 1),
            "byte " + std::to_string(stream) +
                ": bad LZF data: back reference before the start of the output"},
           {"e18.pcd", edit(a, "WIDTH 4\nHEIGHT 1", "WIDTH 65536\nHEIGHT 65536"),
            "line 11: WIDTH x HEIGHT 65536 x 65536: at most 2^32 - 2 points"},
       }) {
    SCOPED_TRACE(name);
    const std::string e = read_error(name, bytes);
    EXPECT_NE(e.find(name + ": " + where), std::string::npos) << e;
  }
}

TEST(ReadPcd, AFileIsToldByItsContentOrNamedUnknown) {
  // PCD and PLY without their extension are told by their first line.
  const Mesh m = read_mesh(write_file("cloud_without_extension", binary_pcd()));
  EXPECT_EQ(m.input_points, 4u);
  // Anything else is not guessed: not a broken STL.
  for (const std::string& bytes : {std::string(200, 'x'), std::string("hello\n"), std::string(100, '\0')}) {
    const std::string e = read_error("scan.dat", bytes);
    EXPECT_NE(e.find("scan.dat: unknown scan format (expected PLY, OBJ, STL, XYZ or PCD)"), std::string::npos)
        << e;
  }
  // Binary STL told by its size, ASCII STL by 'solid'.
  std::string stl(80, ' ');
  put<std::uint32_t>(stl, 1);
  for (float v : {0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) put<float>(stl, v);
  stl += std::string(2, '\0');
  EXPECT_EQ(read_mesh(write_file("binary_stl_without_extension", stl)).triangles.size(), 1u);
}

// Every cut and any corrupted bytes of each encoding: read or reported, never a crash.
TEST(ReadPcd, TruncationAndCorruptionNeverCrash) {
  int errors = 0;
  std::uint32_t seed = 7;
  for (const std::string& file : {ascii_pcd(), binary_pcd(), compressed_pcd()})
    for (std::size_t n = 0; n < file.size(); ++n) {
      std::string corrupt = file;
      for (int k = 0; k < 3; ++k) {
        seed = seed * 1664525u + 1013904223u;
        corrupt[seed % corrupt.size()] = static_cast<char>(seed >> 24);
      }
      for (const std::string& bytes : {file.substr(0, n), corrupt}) try {
          (void)detail::read_pcd("f.pcd", bytes);
        } catch (const IngestError&) {
          ++errors;
        }
    }
  EXPECT_GT(errors, 500);
}

}  // namespace
}  // namespace dentmark::ingest
