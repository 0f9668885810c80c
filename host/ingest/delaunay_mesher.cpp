#include "delaunay_mesher.h"

#include <CGAL/Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <thread>
#include <utility>

namespace dentmark::ingest {
namespace {

// Exact predicates: image positions of neighbouring points differ in their last bits
// at a metre of range and 0.3 mm spacing, where inexact orientation tests break a
// triangulation.
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using VertexBase = CGAL::Triangulation_vertex_base_with_info_2<std::uint32_t, Kernel>;
using Structure = CGAL::Triangulation_data_structure_2<VertexBase>;
using Delaunay = CGAL::Delaunay_triangulation_2<Kernel, Structure>;
using Triangle = std::array<std::uint32_t, 3>;

// The Delaunay triangles of the points with image x in [lo - margin, hi + margin) whose
// centroid lies in [lo, hi): the triangulation is local, so with a margin of many
// spacings these are the triangles of the whole cloud's triangulation there.
std::vector<Triangle> strip_triangles(const std::vector<Eigen::Vector2d>& img,
                                      const std::vector<std::uint32_t>& valid, double lo, double hi,
                                      double margin) {
  std::vector<std::pair<Kernel::Point_2, std::uint32_t>> points;
  for (const std::uint32_t i : valid)
    if (img[i].x() >= lo - margin && img[i].x() < hi + margin)
      points.emplace_back(Kernel::Point_2(img[i].x(), img[i].y()), i);
  // Inserted as a range: CGAL sorts it along a Hilbert curve first (points at the same
  // image position keep the first one's index).
  const Delaunay triangulation(points.begin(), points.end());
  std::vector<Triangle> out;
  out.reserve(2 * points.size());
  for (auto f = triangulation.finite_faces_begin(); f != triangulation.finite_faces_end(); ++f) {
    const Triangle t{f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info()};
    const double cx = (img[t[0]].x() + img[t[1]].x() + img[t[2]].x()) / 3.0;
    if (cx >= lo && cx < hi) out.push_back(t);
  }
  return out;
}

}  // namespace

void mesh_delaunay(Mesh& mesh, const std::vector<Eigen::Vector2d>& img,
                   const std::vector<std::uint32_t>& valid) {
  if (valid.size() < 3) return;
  // Strips of as many points each across the image, one per thread, overlapping by 32
  // mean spacings.
  std::vector<double> x;
  x.reserve(valid.size());
  double ylo = img[valid[0]].y(), yhi = ylo;
  for (const std::uint32_t i : valid) {
    x.push_back(img[i].x());
    ylo = std::min(ylo, img[i].y()), yhi = std::max(yhi, img[i].y());
  }
  std::sort(x.begin(), x.end());
  const double spacing = std::sqrt(std::max(x.back() - x.front(), 1e-12) * std::max(yhi - ylo, 1e-12) /
                                   static_cast<double>(x.size()));
  const std::size_t strips =
      valid.size() < 200000 ? 1 : std::clamp<std::size_t>(std::thread::hardware_concurrency(), 1, 8);
  std::vector<double> bound(strips + 1);
  for (std::size_t s = 1; s < strips; ++s) bound[s] = x[x.size() * s / strips];
  bound.front() = x.front() - 1.0, bound.back() = x.back() + 1.0;
  std::vector<std::vector<Triangle>> found(strips);
  {
    std::vector<std::thread> threads;
    for (std::size_t s = 0; s < strips; ++s)
      threads.emplace_back(
          [&, s] { found[s] = strip_triangles(img, valid, bound[s], bound[s + 1], 32.0 * spacing); });
    for (auto& t : threads) t.join();
  }
  const auto& pts = mesh.vertices;
  const auto edge = [&](std::uint32_t a, std::uint32_t b) { return (pts[a] - pts[b]).norm(); };
  // The median edge: the spacing, for the depth-jump test.
  std::vector<float> edges;
  for (const auto& faces : found) {
    const std::size_t stride = std::max<std::size_t>(1, faces.size() / 50000);
    for (std::size_t i = 0; i < faces.size(); i += stride) edges.push_back(edge(faces[i][0], faces[i][1]));
  }
  if (edges.empty()) return;
  const auto mid = edges.begin() + static_cast<std::ptrdiff_t>(edges.size() / 2);
  std::nth_element(edges.begin(), mid, edges.end());
  // Longer edges are depth jumps or openings; a circumradius over 3 median edges is a
  // sliver along the convex hull (a grid's triangles have about 0.7).
  const float max_edge = 4.0f * *mid, max_circumradius = 3.0f * *mid;
  for (const auto& faces : found)
    for (const auto& t : faces) {
      const float a = edge(t[0], t[1]), b = edge(t[1], t[2]), c = edge(t[2], t[0]);
      if (!(a <= max_edge && b <= max_edge && c <= max_edge)) continue;
      const float area2 = (pts[t[1]] - pts[t[0]]).cross(pts[t[2]] - pts[t[0]]).norm();  // twice the area
      if (a * b * c <= 2.0f * max_circumradius * area2) mesh.triangles.push_back(t);    // R = abc / (4 area)
    }
}

}  // namespace dentmark::ingest
