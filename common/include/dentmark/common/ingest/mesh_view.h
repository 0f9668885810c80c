#pragma once
// A read-only view of a triangle mesh in memory someone else owns: a Mesh, or the vertex
// and face blocks of a binary PLY used in place in the mapped file (no copy of a 170 MB
// scan: on a VM every fresh megabyte costs milliseconds of page faults). Vertices are
// three consecutive floats every `vertex_stride` bytes; triangles three 32-bit indices
// every `triangle_stride` bytes. Everything the detector reads goes through here.

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <vector>

#include "dentmark/common/ingest/mesh.h"

namespace dentmark::ingest {

// The bounding box (in metres) of each run of kSize consecutive vertices. A scanner
// stores its points row by row, so a run is a short strip of the surface, and a pass that
// wants the vertices of a few small regions skips the runs whose box misses them all.
struct VertexBlocks {
  static constexpr std::size_t kSize = 256;
  std::vector<Eigen::Vector3f> lo, hi;  // block b: vertices [b kSize, (b + 1) kSize)
};

class MeshView {
 public:
  MeshView() = default;
  // Every Mesh is a view of itself (implicit: detect(mesh, ...) takes either).
  MeshView(const Mesh& mesh)  // NOLINT(google-explicit-constructor)
      : vertices_(reinterpret_cast<const std::byte*>(mesh.vertices.data())),
        triangles_(reinterpret_cast<const std::byte*>(mesh.triangles.data())),
        vertex_count_(mesh.vertices.size()),
        triangle_count_(mesh.triangles.size()),
        vertex_stride_(sizeof(Eigen::Vector3f)),
        triangle_stride_(sizeof(std::array<std::uint32_t, 3>)) {}
  // `scale` converts the stored coordinates to metres. The caller guarantees that every
  // index is below vertex_count and every coordinate is finite.
  MeshView(const std::byte* vertices, std::size_t vertex_count, std::size_t vertex_stride,
           const std::byte* triangles, std::size_t triangle_count, std::size_t triangle_stride, float scale)
      : vertices_(vertices),
        triangles_(triangles),
        vertex_count_(vertex_count),
        triangle_count_(triangle_count),
        vertex_stride_(vertex_stride),
        triangle_stride_(triangle_stride),
        scale_(scale) {}

  std::size_t vertex_count() const { return vertex_count_; }
  std::size_t triangle_count() const { return triangle_count_; }

  Eigen::Vector3f vertex(std::size_t i) const { return stored_vertex(i) * scale_; }
  // A vertex as stored, before scale() takes it to metres (for loops that scale many at
  // once, or skip it at 1).
  Eigen::Vector3f stored_vertex(std::size_t i) const {
    // One load per float: a copy of all three at once became 8 + 4-byte loads whose
    // floats were then read back through the stack (a store-forwarding stall per vertex).
    const std::byte* p = vertex_address(i);
    float x, y, z;
    std::memcpy(&x, p, sizeof x), std::memcpy(&y, p + 4, sizeof y), std::memcpy(&z, p + 8, sizeof z);
    return {x, y, z};
  }
  float scale() const { return scale_; }
  std::array<std::uint32_t, 3> triangle(std::size_t i) const {
    std::array<std::uint32_t, 3> t;
    std::memcpy(t.data(), triangles_ + i * triangle_stride_, sizeof t);
    return t;
  }
  // The vertices' bounding box (in metres), when whoever made the view measured it on
  // the way (the in-place PLY check does); consumers compute it otherwise.
  bool has_bounds() const { return has_bounds_; }
  const Eigen::Vector3f& bounds_min() const { return min_; }
  const Eigen::Vector3f& bounds_max() const { return max_; }
  void set_bounds(const Eigen::Vector3f& min, const Eigen::Vector3f& max) {
    min_ = min, max_ = max, has_bounds_ = true;
  }
  // The vertex blocks' boxes, when whoever made the view measured them (the in-place PLY
  // check does); null otherwise.
  const VertexBlocks* vertex_blocks() const { return blocks_.get(); }
  void set_vertex_blocks(std::shared_ptr<const VertexBlocks> blocks) { blocks_ = std::move(blocks); }

  // For prefetching ahead of random gathers.
  const std::byte* vertex_address(std::size_t i) const { return vertices_ + i * vertex_stride_; }
  const std::byte* triangle_address(std::size_t i) const { return triangles_ + i * triangle_stride_; }

 private:
  const std::byte* vertices_ = nullptr;
  const std::byte* triangles_ = nullptr;
  std::size_t vertex_count_ = 0, triangle_count_ = 0;
  std::size_t vertex_stride_ = sizeof(Eigen::Vector3f), triangle_stride_ = 12;
  float scale_ = 1.0f;
  bool has_bounds_ = false;
  Eigen::Vector3f min_ = Eigen::Vector3f::Zero(), max_ = Eigen::Vector3f::Zero();
  std::shared_ptr<const VertexBlocks> blocks_;
};

}  // namespace dentmark::ingest
