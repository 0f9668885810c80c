#include "dentmark/host/ingest/read_mesh.h"

#include <algorithm>
#include <cctype>
#include <cmath>

#include "dentmark/common/ingest/detail/mapped_file.h"
#include "dentmark/common/ingest/detail/readers.h"
#include "dentmark/common/ingest/read_scan_file.h"
#include "dentmark/host/ingest/cloud_mesher.h"

namespace dentmark::ingest {

namespace {

// The file read, and a point cloud meshed in the sensor's view.
Mesh read_mapped(const std::string& path, std::string_view bytes, Format format, const ReadOptions& options) {
  Mesh mesh = detail::read_scan_bytes(path, bytes, format, options);
  if (mesh.triangles.empty()) {
    mesh_point_cloud(mesh);
    if (mesh.triangles.empty())
      throw IngestError(path + ": the point cloud could not be meshed (points too sparse or collinear)");
  }
  if (options.progress) options.progress(1.0);
  return mesh;
}

}  // namespace

Mesh read_mesh(const std::string& path, const ReadOptions& options) {
  detail::check_scale(path, options);
  const detail::MappedFile file(path);
  return read_mapped(path, file.view(), detail::resolve_format(path, file.view(), options), options);
}

Scan open_scan(const std::string& path, const ReadOptions& options) {
  detail::check_scale(path, options);
  auto file = std::make_shared<const detail::MappedFile>(path);
  const Format format = detail::resolve_format(path, file->view(), options);
  Scan scan;
  if (format == Format::kPly) {
    if (auto view = detail::ply_in_place(path, file->view(), static_cast<float>(options.scale_to_m));
        view && !detail::is_triangle_soup(view->vertex_count(), view->triangle_count())) {
      scan.mesh = *view;
      scan.input_points = view->vertex_count();
      scan.in_place = true;
      scan.storage = std::move(file);
      if (options.progress) options.progress(1.0);
      return scan;
    }
  }
  auto mesh = std::make_shared<const Mesh>(read_mapped(path, file->view(), format, options));
  file.reset();
  scan.mesh = *mesh;
  scan.input_points = mesh->input_points;
  scan.dropped_faces = mesh->dropped_faces;
  scan.nonfinite_vertices = mesh->nonfinite_vertices;
  scan.from_point_cloud = mesh->from_point_cloud;
  scan.cloud_charts = mesh->cloud_charts;
  scan.storage = std::move(mesh);
  return scan;
}

}  // namespace dentmark::ingest
