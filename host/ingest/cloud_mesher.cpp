#include "dentmark/host/ingest/cloud_mesher.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "delaunay_mesher.h"
#include "dentmark/common/nth_smallest.h"
#include "fold_mesher.h"

namespace dentmark::ingest {
namespace {

// Image coordinates of each point in the chosen view.
struct View {
  bool perspective = true;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  // rows: image axes u, v, depth
};

View choose_view(const std::vector<Eigen::Vector3f>& pts) {
  View view;
  bool all_front = true;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  std::size_t n = 0;
  for (const auto& p : pts) {
    if (!p.allFinite()) continue;
    if (p.z() <= 0.0f) all_front = false;
    mean += p.cast<double>();
    ++n;
  }
  mean /= static_cast<double>(std::max<std::size_t>(n, 1));
  // A perspective view only makes sense when the points are well in front of the
  // origin (a sensor frame); otherwise look along the least-variance axis.
  if (all_front && mean.z() > 0.0) {
    double max_tan = 0.0;
    for (const auto& p : pts)
      if (p.allFinite()) max_tan = std::max<double>(max_tan, std::hypot(p.x(), p.y()) / p.z());
    if (max_tan < 3.0) return view;
  }
  view.perspective = false;
  Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
  for (const auto& p : pts) {
    if (!p.allFinite()) continue;
    const Eigen::Vector3d d = p.cast<double>() - mean;
    c += d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(c);
  // Depth along +z where the axis allows: a profiler's heights and a part frame's "up"
  // face that way.
  const double sign = eig.eigenvectors().col(0).z() < 0.0 ? -1.0 : 1.0;
  view.R.row(0) = eig.eigenvectors().col(2).transpose();
  view.R.row(1) = sign * eig.eigenvectors().col(1).transpose();
  view.R.row(2) = sign * eig.eigenvectors().col(0).transpose();
  return view;
}

// 3D distances between image neighbours above this are depth jumps, not surface.
float max_edge_of(std::vector<float>& neighbour_distances) {
  if (neighbour_distances.empty()) return std::numeric_limits<float>::max();
  return 4.0f * median_in_place(neighbour_distances);
}

// An organised cloud, as a camera writes it: the points in raster order, row after row
// (the missing ones left out or NaN). Then each row is stitched to the next, every point
// kept, whatever the density: a panel at 55 degrees to the view is twice as dense at its
// far end as at its near one, which no single grid cell fits. Returns false when the
// order is not that of rows (the caller then meshes on a grid).
bool mesh_raster_rows(Mesh& mesh, const std::vector<Eigen::Vector2d>& img,
                      const std::vector<std::uint32_t>& valid) {
  const auto& pts = mesh.vertices;
  const std::size_t n = valid.size();
  if (n < 64) return false;
  // Along a row the image steps are alike; the median step is the row's direction.
  std::vector<double> dx, dy;
  const std::size_t stride = std::max<std::size_t>(1, n / 100000);
  for (std::size_t i = 0; i + 1 < n; i += stride) {
    const Eigen::Vector2d d = img[valid[i + 1]] - img[valid[i]];
    dx.push_back(d.x()), dy.push_back(d.y());
  }
  const Eigen::Vector2d step(median_in_place(dx), median_in_place(dy));
  if (!(step.norm() > 0.0)) return false;
  const Eigen::Vector2d along = step.normalized();
  // Rows: runs that go forward along it (a gap of missing points goes forward too; the
  // next row starts back at the other side).
  std::vector<double> t(n);
  for (std::size_t i = 0; i < n; ++i) t[i] = img[valid[i]].dot(along);
  std::vector<std::size_t> row_start{0};
  for (std::size_t i = 1; i < n; ++i)
    if (t[i] <= t[i - 1]) row_start.push_back(i);
  row_start.push_back(n);
  const std::size_t rows = row_start.size() - 1;
  if (rows < 3 || n / rows < 8) return false;
  std::vector<float> along_row;
  for (std::size_t r = 0; r < rows && along_row.size() < 200000; r += std::max<std::size_t>(1, rows / 2000))
    for (std::size_t i = row_start[r]; i + 1 < row_start[r + 1]; ++i)
      along_row.push_back((pts[valid[i]] - pts[valid[i + 1]]).norm());
  const float max_edge = max_edge_of(along_row);
  const auto ok = [&](std::uint32_t a, std::uint32_t b) { return (pts[a] - pts[b]).norm() <= max_edge; };
  std::vector<std::array<std::uint32_t, 3>> triangles;
  triangles.reserve(2 * n);
  const auto add = [&](std::size_t a, std::size_t b, std::size_t c) {
    const std::uint32_t p = valid[a], q = valid[b], r = valid[c];
    if (ok(p, q) && ok(q, r) && ok(p, r)) triangles.push_back({p, q, r});
  };
  // Zip each row to the next: advance on the row whose next point comes first.
  for (std::size_t r = 0; r + 1 < rows; ++r) {
    const std::size_t a1 = row_start[r + 1], b1 = row_start[r + 2];
    std::size_t i = row_start[r], j = row_start[r + 1];
    while (i + 1 < a1 || j + 1 < b1) {
      if (j + 1 >= b1 || (i + 1 < a1 && t[i + 1] <= t[j + 1])) {
        add(i, i + 1, j);
        ++i;
      } else {
        add(i, j + 1, j);
        ++j;
      }
    }
  }
  // Rows that are not the camera's (a cloud sorted some other way) leave most points
  // without triangles: a grid serves those better.
  if (triangles.size() < n) return false;
  mesh.triangles = std::move(triangles);
  return true;
}

// Triangles facing the viewer: the sensor at the origin in a perspective view, the +depth
// side in an orthographic one (what the PLY shows to a viewer that culls back faces, and
// the side a scan without a sensor at its origin takes for outside).
void face_the_view(Mesh& mesh, const View& view) {
  std::size_t towards = 0, away = 0;
  const std::size_t stride = std::max<std::size_t>(1, mesh.triangles.size() / 10000);
  for (std::size_t i = 0; i < mesh.triangles.size(); i += stride) {
    const auto& t = mesh.triangles[i];
    const Eigen::Vector3d a = mesh.vertices[t[0]].cast<double>(), b = mesh.vertices[t[1]].cast<double>(),
                          c = mesh.vertices[t[2]].cast<double>();
    const Eigen::Vector3d n = (b - a).cross(c - a);
    const Eigen::Vector3d to_viewer =
        view.perspective ? Eigen::Vector3d(-a) : Eigen::Vector3d(view.R.row(2).transpose());
    (n.dot(to_viewer) >= 0.0 ? towards : away) += 1;
  }
  if (away > towards)
    for (auto& t : mesh.triangles) std::swap(t[1], t[2]);
}

}  // namespace

void mesh_point_cloud(Mesh& mesh) {
  mesh.triangles.clear();
  mesh.from_point_cloud = true;
  const auto& pts = mesh.vertices;
  const View view = choose_view(pts);
  std::vector<Eigen::Vector2d> img(pts.size());
  std::vector<std::uint32_t> valid;
  valid.reserve(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (!pts[i].allFinite()) continue;
    const Eigen::Vector3d q = view.R * pts[i].cast<double>();
    img[i] = view.perspective ? Eigen::Vector2d(q.x() / q.z(), q.y() / q.z()) : Eigen::Vector2d(q.x(), q.y());
    valid.push_back(static_cast<std::uint32_t>(i));
  }
  if (valid.size() < 3) return;
  if (mesh_raster_rows(mesh, img, valid)) {
    face_the_view(mesh, view);
    return;
  }
  // Merged views that wrap round: charts, facing the way the side nearest the view does.
  mesh.cloud_charts =
      mesh_folded_cloud(mesh, valid, ViewDirection{view.perspective, view.R.row(2).transpose()});
  if (mesh.cloud_charts > 0) return;
  mesh_delaunay(mesh, img, valid);
  face_the_view(mesh, view);
}

}  // namespace dentmark::ingest
