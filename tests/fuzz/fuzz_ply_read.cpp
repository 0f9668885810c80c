// libFuzzer target for the scan readers: PLY, its in-place scanner layout, OBJ, STL,
// XYZ and PCD (ascii, binary, binary_compressed with its LZF decoder). None may crash, hang or read out of
// bounds (ASan/UBSan); every index a reader hands on is in range; a file accepted in place must be read by
// the copying PLY reader into the same mesh; and rewinding what was read (orient_triangles.h) keeps every
// triangle's corners, at most reversed.
#include <array>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string_view>

#include "dentmark/common/ingest/detail/readers.h"
#include "dentmark/host/ingest/orient_triangles.h"

namespace in = dentmark::ingest;

namespace {

void check_indices(const in::Mesh& m) {
  for (const auto& t : m.triangles)
    for (auto i : t)
      if (i >= m.vertices.size()) std::abort();
}

// The same corners in the same or the reversed cyclic order.
bool same_or_reversed(const std::array<std::uint32_t, 3>& a, const std::array<std::uint32_t, 3>& b) {
  for (int r = 0; r < 3; ++r)
    if ((a[0] == b[r] && a[1] == b[(r + 1) % 3] && a[2] == b[(r + 2) % 3]) ||
        (a[0] == b[r] && a[1] == b[(r + 2) % 3] && a[2] == b[(r + 1) % 3]))
      return true;
  return false;
}

void check_rewinding(const in::Mesh& m) {
  (void)in::has_opposed_neighbours(m);
  (void)in::large_parts(m, 2);
  const auto oriented = in::orient_consistently(m);
  if (!oriented) return;
  if (oriented->mesh.triangles.size() != m.triangles.size() || oriented->flipped == 0 ||
      oriented->flipped > m.triangles.size())
    std::abort();
  for (std::size_t t = 0; t < m.triangles.size(); ++t)
    if (!same_or_reversed(oriented->mesh.triangles[t], m.triangles[t])) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  std::optional<in::MeshView> view;
  try {
    view = in::detail::ply_in_place("fuzz.ply", bytes, 1.0f);
  } catch (const in::IngestError&) {
  }
  in::Mesh mesh;
  bool read = false;
  try {
    mesh = in::detail::read_ply("fuzz.ply", bytes);
    read = true;
  } catch (const in::IngestError&) {
  }
  if (read) check_indices(mesh), check_rewinding(mesh);
  for (auto reader :
       {in::detail::read_obj, in::detail::read_stl, in::detail::read_xyz, in::detail::read_pcd}) {
    try {
      const in::Mesh m = reader("fuzz", bytes);
      check_indices(m);
      check_rewinding(m);
    } catch (const in::IngestError&) {
    }
  }
  if (view) {
    if (!read || view->vertex_count() != mesh.vertices.size() ||
        view->triangle_count() != mesh.triangles.size())
      std::abort();
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
      const Eigen::Vector3f v = view->vertex(i);
      if (!v.allFinite() || std::memcmp(v.data(), mesh.vertices[i].data(), sizeof(float) * 3) != 0)
        std::abort();
    }
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t)
      if (view->triangle(t) != mesh.triangles[t]) std::abort();
  }
  return 0;
}
