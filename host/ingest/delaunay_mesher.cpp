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

#include "dentmark/common/nth_smallest.h"

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
    const double cx =
        (f->vertex(0)->point().x() + f->vertex(1)->point().x() + f->vertex(2)->point().x()) / 3.0;
    if (cx >= lo && cx < hi)
      out.push_back({f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info()});
  }
  return out;
}

// Keeps the triangles with no 3D edge over max_edge and a circumradius of at most
// max_circumradius.
void keep_surface(std::vector<Triangle>& faces, const std::vector<Eigen::Vector3f>& pts, float max_edge,
                  float max_circumradius) {
  std::erase_if(faces, [&](const Triangle& t) {
    const float a = (pts[t[0]] - pts[t[1]]).norm(), b = (pts[t[1]] - pts[t[2]]).norm(),
                c = (pts[t[2]] - pts[t[0]]).norm();
    if (!(a <= max_edge && b <= max_edge && c <= max_edge)) return true;
    const float area2 = (pts[t[1]] - pts[t[0]]).cross(pts[t[2]] - pts[t[0]]).norm();  // twice the area
    return a * b * c > 2.0f * max_circumradius * area2;                               // R = abc / (4 area)
  });
}

// Runs job(s) for s in [0, n), one thread each.
template <typename Job>
void in_threads(std::size_t n, Job job) {
  std::vector<std::thread> threads;
  for (std::size_t s = 0; s < n; ++s) threads.emplace_back(job, s);
  for (auto& t : threads) t.join();
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
  const auto [xlo, xhi] = std::minmax_element(x.begin(), x.end());
  const double spacing =
      std::sqrt(std::max(*xhi - *xlo, 1e-12) * std::max(yhi - ylo, 1e-12) / static_cast<double>(x.size()));
  const std::size_t strips =
      valid.size() < 200000 ? 1 : std::clamp<std::size_t>(std::thread::hardware_concurrency(), 1, 8);
  std::vector<double> bound(strips + 1);
  bound.front() = *xlo - 1.0, bound.back() = *xhi + 1.0;
  for (std::size_t s = 1; s < strips; ++s) {
    bound[s] = nth_smallest(x, x.size() * s / strips);
  }
  std::vector<std::vector<Triangle>> found(strips);
  in_threads(strips, [&](std::size_t s) {
    found[s] = strip_triangles(img, valid, bound[s], bound[s + 1], 32.0 * spacing);
  });
  // The median edge: the spacing, for the depth-jump test.
  const auto& pts = mesh.vertices;
  std::vector<float> edges;
  for (const auto& faces : found) {
    const std::size_t stride = std::max<std::size_t>(1, faces.size() / 50000);
    for (std::size_t i = 0; i < faces.size(); i += stride)
      edges.push_back((pts[faces[i][0]] - pts[faces[i][1]]).norm());
  }
  if (edges.empty()) return;
  const float median_edge = median_in_place(edges);
  // Longer edges are depth jumps or openings; a circumradius over 3 median edges is a
  // sliver along the convex hull (a grid's triangles have about 0.7).
  in_threads(strips,
             [&](std::size_t s) { keep_surface(found[s], pts, 4.0f * median_edge, 3.0f * median_edge); });
  for (const auto& faces : found) mesh.triangles.insert(mesh.triangles.end(), faces.begin(), faces.end());
}

}  // namespace dentmark::ingest
