#include "dentmark/common/ingest/read_scan_file.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include "dentmark/common/ingest/detail/mapped_file.h"
#include "dentmark/common/ingest/detail/readers.h"

namespace dentmark::ingest {

Format format_from_path(const std::string& path) {
  const auto dot = path.find_last_of('.');
  if (dot == std::string::npos) return Format::kAuto;
  std::string ext = path.substr(dot + 1);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext == "ply") return Format::kPly;
  if (ext == "obj") return Format::kObj;
  if (ext == "stl") return Format::kStl;
  if (ext == "pcd") return Format::kPcd;
  if (ext == "xyz" || ext == "txt" || ext == "pts" || ext == "asc" || ext == "csv") return Format::kXyz;
  return Format::kAuto;
}

namespace {

// What the bytes say, for a file whose name does not: PLY and PCD by their first line,
// ASCII STL by 'solid', binary STL by a facet count that gives exactly the file's size.
Format format_from_content(std::string_view bytes) {
  if (bytes.starts_with("ply")) return Format::kPly;
  if (bytes.starts_with("# .PCD") || bytes.starts_with("VERSION") || bytes.starts_with("FIELDS"))
    return Format::kPcd;
  std::string_view text = bytes.substr(bytes.starts_with("\xEF\xBB\xBF") ? 3 : 0);
  while (!text.empty() && std::isspace(static_cast<unsigned char>(text.front()))) text.remove_prefix(1);
  if (text.size() >= 5) {
    std::string head(text.substr(0, 5));
    std::transform(head.begin(), head.end(), head.begin(), [](unsigned char c) { return std::tolower(c); });
    if (head == "solid") return Format::kStl;
  }
  if (bytes.size() >= 84) {
    std::uint32_t facets = 0;
    std::memcpy(&facets, bytes.data() + 80, 4);
    if (84 + 50ull * facets == bytes.size()) return Format::kStl;
  }
  return Format::kAuto;
}

}  // namespace

namespace detail {

void check_scale(const std::string& path, const ReadOptions& options) {
  if (!(options.scale_to_m > 0.0) || !std::isfinite(options.scale_to_m))
    throw IngestError(path + ": scale to metres must be positive");
}

Format resolve_format(const std::string& path, std::string_view bytes, const ReadOptions& options) {
  if (bytes.empty()) throw IngestError(path + ": byte 0: file is empty");
  Format format = options.format == Format::kAuto ? format_from_path(path) : options.format;
  if (format == Format::kAuto) format = format_from_content(bytes);
  if (format == Format::kAuto)
    throw IngestError(path + ": unknown scan format (expected PLY, OBJ, STL, XYZ or PCD)");
  return format;
}

// A mesh has about half as many vertices as triangles, a soup three times as many. Its
// coincident corners are welded (weld_vertices): the host's rewinding walks shared edges.
bool is_triangle_soup(std::size_t vertices, std::size_t triangles) {
  return triangles > 0 && 2 * vertices > 5 * triangles;
}

Mesh read_scan_bytes(const std::string& path, std::string_view bytes, Format format,
                     const ReadOptions& options) {
  Mesh mesh;
  switch (format) {
    case Format::kPly:
      mesh = read_ply(path, bytes);
      break;
    case Format::kObj:
      mesh = read_obj(path, bytes);
      break;
    case Format::kStl:
      mesh = read_stl(path, bytes);
      break;
    case Format::kPcd:
      mesh = read_pcd(path, bytes);
      break;
    case Format::kXyz:
    case Format::kAuto:
      mesh = read_xyz(path, bytes);
      break;
  }
  if (options.progress) options.progress(0.7);
  mesh.input_points = mesh.vertices.size();
  if (mesh.vertices.size() >= (1ull << 32) - 1)
    throw IngestError(path + ": more than 4 billion vertices are not supported");

  // Units and non-finite values: a non-finite vertex poisons the faces that use it.
  const float s = static_cast<float>(options.scale_to_m);
  std::size_t nonfinite = 0;
  const auto nv = static_cast<std::int64_t>(mesh.vertices.size());
#pragma omp parallel for reduction(+ : nonfinite) schedule(static)
  for (std::int64_t i = 0; i < nv; ++i) {
    Eigen::Vector3f& v = mesh.vertices[i];
    if (!v.allFinite()) {
      ++nonfinite;
      v.setConstant(std::numeric_limits<float>::quiet_NaN());
    } else if (s != 1.0f) {
      v *= s;
    }
  }
  mesh.nonfinite_vertices = nonfinite;
  if (nonfinite > 0 && !mesh.triangles.empty()) {
    const auto before = mesh.triangles.size();
    std::erase_if(mesh.triangles, [&](const std::array<std::uint32_t, 3>& t) {
      return !(mesh.vertices[t[0]].allFinite() && mesh.vertices[t[1]].allFinite() &&
               mesh.vertices[t[2]].allFinite());
    });
    mesh.dropped_faces += before - mesh.triangles.size();
  }
  if (is_triangle_soup(mesh.vertices.size(), mesh.triangles.size())) weld_vertices(mesh);
  if (mesh.triangles.empty()) {
    // Organized clouds (a point per camera pixel) may mark a pixel without a measurement
    // by a point at the sensor, (0, 0, 0), instead of NaN: no surface is there. (At most
    // one real point can sit exactly there.)
    for (auto& v : mesh.vertices)
      if (v.x() == 0.0f && v.y() == 0.0f && v.z() == 0.0f) {
        v.setConstant(std::numeric_limits<float>::quiet_NaN());
        ++nonfinite;
      }
    mesh.nonfinite_vertices = nonfinite;
    if (mesh.vertices.size() - nonfinite < 3)
      throw IngestError(path + ": fewer than 3 usable points and no faces: nothing to inspect");
  }
  return mesh;
}

}  // namespace detail

Mesh read_scan_file(const std::string& path, const ReadOptions& options) {
  detail::check_scale(path, options);
  const detail::MappedFile file(path);
  Mesh mesh =
      detail::read_scan_bytes(path, file.view(), detail::resolve_format(path, file.view(), options), options);
  if (options.progress) options.progress(1.0);
  return mesh;
}

}  // namespace dentmark::ingest
