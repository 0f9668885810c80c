// STL, binary (80-byte header, uint32 count, 50 bytes per facet) and ascii ('solid ...
// facet ... vertex x y z ... endsolid'). Facets keep their own three vertices.
#include <cstdint>
#include <cstring>

#include "readers.h"
#include "text_cursor.h"

namespace dentmark::ingest::detail {
namespace {

bool looks_binary(std::string_view b) {
  if (b.size() < 84) return false;
  std::uint32_t n = 0;
  std::memcpy(&n, b.data() + 80, 4);
  return 84 + 50ull * n == b.size();
}

}  // namespace

Mesh read_stl(const std::string& path, std::string_view bytes) {
  Mesh mesh;
  if (looks_binary(bytes)) {
    std::uint32_t n = 0;
    std::memcpy(&n, bytes.data() + 80, 4);
    mesh.vertices.resize(3ull * n);
    mesh.triangles.resize(n);
    const char* base = bytes.data() + 84;
#pragma omp parallel for schedule(static)
    for (std::int64_t i = 0; i < static_cast<std::int64_t>(n); ++i) {
      float v[9];
      std::memcpy(v, base + 50 * i + 12, sizeof v);  // skip the facet normal
      for (int k = 0; k < 3; ++k) {
        mesh.vertices[3 * i + k] = Eigen::Vector3f(v[3 * k], v[3 * k + 1], v[3 * k + 2]);
      }
      const auto b = static_cast<std::uint32_t>(3 * i);
      mesh.triangles[i] = {b, b + 1, b + 2};
    }
    return mesh;
  }
  if (bytes.substr(0, 5) != "solid") {
    if (bytes.size() >= 84)
      throw IngestError(path + ": byte 80: binary STL facet count does not match the file size " +
                        std::to_string(bytes.size()));
    throw IngestError(path + ": byte 0: neither binary STL (too short) nor ascii STL (no 'solid')");
  }
  TextCursor cur(path, bytes);
  cur.next_line();
  int in_loop = -1;
  while (true) {
    cur.skip_space();
    if (cur.at_end()) break;
    const std::string_view key = cur.word();
    if (key == "outer") {
      in_loop = 0;
    } else if (key == "vertex") {
      if (in_loop < 0 || in_loop >= 3) cur.fail("'vertex' outside a 3-vertex loop");
      const double x = cur.number("x"), y = cur.number("y"), z = cur.number("z");
      mesh.vertices.emplace_back(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
      ++in_loop;
    } else if (key == "endloop") {
      if (in_loop != 3)
        cur.fail("facet loop with " + std::to_string(in_loop < 0 ? 0 : in_loop) + " vertices");
      const auto b = static_cast<std::uint32_t>(mesh.vertices.size() - 3);
      mesh.triangles.push_back({b, b + 1, b + 2});
      in_loop = -1;
    } else if (key == "facet" || key == "endfacet" || key == "endsolid" || key == "solid") {
    } else {
      cur.fail("unexpected '" + std::string(key.substr(0, 32)) + "' in ascii STL");
    }
    cur.next_line();
  }
  if (in_loop >= 0) cur.fail("file ends inside a facet");
  return mesh;
}

}  // namespace dentmark::ingest::detail
