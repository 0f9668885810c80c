// libFuzzer target for the scan readers: PLY, its in-place scanner layout, OBJ, STL and
// XYZ. None may crash, hang or read out of bounds (ASan/UBSan); every index a reader hands
// on is in range; and a file accepted in place must be read by the copying PLY reader
// into the same mesh.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string_view>

#include "../../host/ingest/readers.h"

namespace in = dentmark::ingest;

namespace {

void check_indices(const in::Mesh& m) {
  for (const auto& t : m.triangles)
    for (auto i : t)
      if (i >= m.vertices.size()) std::abort();
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
  if (read) check_indices(mesh);
  for (auto reader : {in::detail::read_obj, in::detail::read_stl, in::detail::read_xyz}) {
    try {
      check_indices(reader("fuzz", bytes));
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
