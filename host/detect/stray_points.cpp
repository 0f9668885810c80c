#include "stray_points.h"

#include <algorithm>
#include <cstdint>
#include <limits>
#include <vector>

#include "dentmark/common/nth_smallest.h"
#include "threads.h"

namespace dentmark::detect {

Box bounding_box(const ingest::MeshView& mesh) {
  if (mesh.has_bounds()) return {mesh.bounds_min(), mesh.bounds_max()};
  Box b{Eigen::Vector3f::Constant(std::numeric_limits<float>::max()),
        Eigen::Vector3f::Constant(-std::numeric_limits<float>::max())};
#pragma omp parallel
  {
    Box part = b;
#pragma omp for nowait schedule(static)
    for (std::int64_t i = 0; i < static_cast<std::int64_t>(mesh.vertex_count()); ++i) {
      const Eigen::Vector3f v = mesh.vertex(static_cast<std::size_t>(i));
      if (v.allFinite()) part.lo = part.lo.cwiseMin(v), part.hi = part.hi.cwiseMax(v);
    }
#pragma omp critical
    b.lo = b.lo.cwiseMin(part.lo), b.hi = b.hi.cwiseMax(part.hi);
  }
  return b;
}

Box middle_box(std::vector<float> (&x)[3]) {
  Box b{Eigen::Vector3f::Constant(-std::numeric_limits<float>::max()),
        Eigen::Vector3f::Constant(std::numeric_limits<float>::max())};
  if (x[0].size() < 100) return b;
  detail::for_each_part(3, [&](std::size_t a) {  // the axes side by side
    const auto at = [&](double f) {
      return nth_smallest(x[a], static_cast<std::size_t>(f * static_cast<double>(x[a].size() - 1)));
    };
    b.lo[static_cast<int>(a)] = at(0.01), b.hi[static_cast<int>(a)] = at(0.99);
  });
  const Eigen::Vector3f m = Eigen::Vector3f::Constant(0.25f * (b.hi - b.lo).maxCoeff());
  b.lo -= m, b.hi += m;
  return b;
}

Box panel_box(const ingest::MeshView& mesh) {
  Box b = bounding_box(mesh);
  const std::size_t stride = std::max<std::size_t>(1, mesh.vertex_count() / 100000);
  std::vector<float> x[3];
  for (std::size_t i = 0; i < mesh.vertex_count(); i += stride) {
    const Eigen::Vector3f v = mesh.vertex(i);
    if (v.allFinite())
      for (int a = 0; a < 3; ++a) x[a].push_back(v[a]);
  }
  const Box middle = middle_box(x);
  b.lo = b.lo.cwiseMax(middle.lo), b.hi = b.hi.cwiseMin(middle.hi);
  return b;
}

ingest::Mesh crop(const ingest::MeshView& mesh, const Box& box, std::size_t& dropped) {
  const auto inside = [&](std::uint32_t i) {
    const Eigen::Vector3f v = mesh.vertex(i);
    return (v.array() >= box.lo.array()).all() && (v.array() <= box.hi.array()).all();
  };
  ingest::Mesh out;
  std::vector<std::uint32_t> renumber(mesh.vertex_count(), std::numeric_limits<std::uint32_t>::max());
  dropped = 0;
  for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
    std::array<std::uint32_t, 3> tri = mesh.triangle(t);
    if (!inside(tri[0]) || !inside(tri[1]) || !inside(tri[2])) {
      ++dropped;
      continue;
    }
    for (auto& i : tri) {
      if (renumber[i] == std::numeric_limits<std::uint32_t>::max()) {
        renumber[i] = static_cast<std::uint32_t>(out.vertices.size());
        out.vertices.push_back(mesh.vertex(i));
      }
      i = renumber[i];
    }
    out.triangles.push_back(tri);
  }
  return out;
}

}  // namespace dentmark::detect
