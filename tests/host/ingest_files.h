#pragma once
// Files for the ingest tests (test_ingest_*.cpp): a scratch folder removed when the test
// process ends, byte writers, and the reference mesh (a unit square split in two plus a
// triangle) in the formats the readers take.

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>

#include "dentmark/host/ingest/read_mesh.h"

namespace dentmark::ingest::testing {

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

inline std::string temp_path(const std::string& name) {
  static const ScratchDir dir;
  return (dir.path() / name).string();
}

inline std::string write_file(const std::string& name, const std::string& bytes) {
  const std::string p = temp_path(name);
  std::ofstream(p, std::ios::binary) << bytes;
  return p;
}

template <typename T>
inline void put(std::string& s, T v, bool big = false) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  if (big) std::reverse(b, b + sizeof(T));
  s.append(b, sizeof(T));
}

// A unit square split in two plus a triangle: 5 vertices, 3 triangles after fans.
inline constexpr float kV[5][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {2, 0, 1}};

inline void expect_reference(const Mesh& m, float scale = 1.0f) {
  ASSERT_EQ(m.vertices.size(), 5u);
  ASSERT_EQ(m.triangles.size(), 3u);
  for (int i = 0; i < 5; ++i)
    for (int a = 0; a < 3; ++a) EXPECT_FLOAT_EQ(m.vertices[i][a], kV[i][a] * scale);
  EXPECT_EQ(m.triangles[0], (std::array<std::uint32_t, 3>{0, 1, 2}));
  EXPECT_EQ(m.triangles[1], (std::array<std::uint32_t, 3>{0, 2, 3}));
  EXPECT_EQ(m.triangles[2], (std::array<std::uint32_t, 3>{1, 4, 2}));
}

inline std::string ascii_ply() {
  std::string s =
      "ply\nformat ascii 1.0\ncomment test\nelement vertex 5\nproperty float x\nproperty float y\n"
      "property float z\nproperty uchar red\nelement face 2\nproperty list uchar int vertex_indices\n"
      "end_header\n";
  for (auto& v : kV)
    s += std::to_string(v[0]) + " " + std::to_string(v[1]) + " " + std::to_string(v[2]) + " 7\n";
  s += "4 0 1 2 3\n3 1 4 2\n";
  return s;
}

inline std::string binary_ply(bool big, bool dbl, const char* count_type, const char* index_type) {
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

// The common scanner layout (only triangles, one list property) takes a parallel path;
// it must read the same and reject the same.
inline std::string triangle_block_ply(int bad_index, const std::string& index_type = "uint") {
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

inline void expect_reference(const MeshView& m, float scale = 1.0f) {
  ASSERT_EQ(m.vertex_count(), 5u);
  ASSERT_EQ(m.triangle_count(), 3u);
  for (std::size_t i = 0; i < 5; ++i)
    for (int a = 0; a < 3; ++a) EXPECT_FLOAT_EQ(m.vertex(i)[a], kV[i][a] * scale);
  EXPECT_EQ(m.triangle(0), (std::array<std::uint32_t, 3>{0, 1, 2}));
  EXPECT_EQ(m.triangle(1), (std::array<std::uint32_t, 3>{0, 2, 3}));
  EXPECT_EQ(m.triangle(2), (std::array<std::uint32_t, 3>{1, 4, 2}));
}

// The IngestError message for reading `bytes` as file `name` (read_mesh, or open_scan
// when `scan`); "" and a test failure when the file is accepted.
inline std::string ingest_error(const std::string& name, const std::string& bytes, bool scan = false) {
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

}  // namespace dentmark::ingest::testing
