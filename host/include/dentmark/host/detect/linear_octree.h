#pragma once
// The paper's octree (§III-A) as a linear octree: every triangle gets the Morton code of
// its centroid at the finest depth; with the leaves in key order, every node at every
// depth is a contiguous range of leaves. Per leaf the additive sums A = Σ a_i (eq. 1) and
// S = Σ a_i N_i are kept, so a node's mean normal (eq. 2) is S/A and its weighted spread
// (eq. 3) is σ² = Σ a_i |N_i − N̄|² / A = 1 − |S/A|² (the N_i are unit vectors): one
// pass of sums gives every node.

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cstdint>
#include <memory>
#include <new>
#include <vector>

#include "dentmark/common/ingest/mesh_view.h"

namespace dentmark::detect {

namespace detail {
// Byte b's bits spread to every third bit (for Morton codes).
constexpr std::array<std::uint32_t, 256> spread_byte_table() {
  std::array<std::uint32_t, 256> table{};
  for (std::uint32_t b = 0; b < 256; ++b)
    for (int i = 0; i < 8; ++i) table[b] |= (b >> i & 1u) << (3 * i);
  return table;
}
inline constexpr std::array<std::uint32_t, 256> kSpreadByte = spread_byte_table();
}  // namespace detail

// 40 bytes: a million leaves are fresh memory, and floats hold what a leaf needs (the
// centroid to 0.1 µm over 2 m; A and S to 1e-7, far below the σ² of a scan's noise).
// Plain data, set in full where leaves are made: their block is allocated without being
// touched first (see OctreeLeaves).
struct OctreeLeaf {
  std::uint64_t key;         // Morton code at the finest depth
  float area;                // A = Σ a_i (m²)
  Eigen::Vector3f sum_an;    // S = Σ a_i N_i (m²)
  Eigen::Vector3f centroid;  // Σ a_i c_i / A, c_i the triangle centroids (m)
  std::uint32_t count;       // triangles in the leaf
};

// The leaves in key order: a window of a block allocated for as many leaves as the build
// could make. Only the window is ever written, so the rest of the block costs address
// space, not memory (the build writes the window from its middle outwards; see
// leaf_sums.cpp).
class OctreeLeaves {
 public:
  OctreeLeaves() = default;
  // A block for up to `capacity` leaves, none in the window yet.
  explicit OctreeLeaves(std::size_t capacity)
      : block_(static_cast<OctreeLeaf*>(
            ::operator new(std::max<std::size_t>(capacity, 1) * sizeof(OctreeLeaf)))) {}
  OctreeLeaf* block() { return block_.get(); }
  // The window: leaves [first, first + size) of the block.
  void set_window(std::size_t first, std::size_t size) { first_ = first, size_ = size; }

  const OctreeLeaf* begin() const { return block_.get() + first_; }
  const OctreeLeaf* end() const { return begin() + size_; }
  const OctreeLeaf& operator[](std::size_t i) const { return begin()[i]; }
  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }

 private:
  struct Free {
    void operator()(OctreeLeaf* p) const { ::operator delete(p); }
  };
  std::unique_ptr<OctreeLeaf, Free> block_;
  std::size_t first_ = 0, size_ = 0;
};

struct NodeStats {
  double area = 0.0;
  Eigen::Vector3d mean_normal = Eigen::Vector3d::Zero();  // eq. (2), not normalised
  double sigma = 0.0;                                     // eq. (3), rad-like
};

class LinearOctree {
 public:
  // Builds the leaves at the depth whose node edge is leaf_size (m). Triangles may come
  // in any order; the triangles are never sorted (see leaf_sums.cpp).
  static LinearOctree build(const ingest::MeshView& mesh, double leaf_size);
  // The deepest octree build() makes: 2^16 finest nodes a side (65 m at 1 mm).
  static constexpr int kMaxDepth = 16;

  const OctreeLeaves& leaves() const { return leaves_; }
  // The same tree with only the leaves whose keep[] is non-zero (one per leaf).
  LinearOctree subset(const std::vector<std::uint8_t>& keep) const;
  // Finest-depth key of the leaf holding triangle t (its centroid's cell).
  std::uint64_t triangle_key(const ingest::MeshView& mesh, std::size_t t) const;
  int depth() const { return depth_; }
  double leaf_size() const { return leaf_size_; }
  const Eigen::Vector3d& origin() const { return origin_; }

  // Eq. (2)-(3) over leaves [begin, end) (sums the range).
  NodeStats stats(std::size_t begin, std::size_t end) const;
  // Top-down subdivision (eq. 3): nodes whose σ exceeds split_sigma are subdivided down
  // to the finest depth; returns the leaves reached whose own σ exceeds leaf_sigma.
  std::vector<std::uint32_t> feature_leaves(double split_sigma, double leaf_sigma) const;
  // Integer cell of a leaf key.
  static Eigen::Vector3i decode(std::uint64_t key) {
    return {static_cast<int>(compact3(key)), static_cast<int>(compact3(key >> 1)),
            static_cast<int>(compact3(key >> 2))};
  }
  static std::uint64_t encode(const Eigen::Vector3i& cell) {
    return spread3(static_cast<std::uint64_t>(cell.x())) |
           spread3(static_cast<std::uint64_t>(cell.y())) << 1 |
           spread3(static_cast<std::uint64_t>(cell.z())) << 2;
  }

  // Memory: the leaves, and the peak of their build (records filed per bucket).
  std::size_t bytes() const;

 private:
  // Spreads the low 21 bits of x to every third bit, a byte at a time through a table
  // (a quarter of the shift-and-mask cascade's instructions; keys are made for every
  // few triangles of a scan), and back.
  static std::uint64_t spread3(std::uint64_t x) {
    return std::uint64_t{detail::kSpreadByte[x & 0xff]} |
           std::uint64_t{detail::kSpreadByte[x >> 8 & 0xff]} << 24 |
           std::uint64_t{detail::kSpreadByte[x >> 16 & 0x1f]} << 48;
  }
  static std::uint64_t compact3(std::uint64_t x) {
    x &= 0x1249249249249249ull;
    x = (x ^ (x >> 2)) & 0x10c30c30c30c30c3ull;
    x = (x ^ (x >> 4)) & 0x100f00f00f00f00full;
    x = (x ^ (x >> 8)) & 0x1f0000ff0000ffull;
    x = (x ^ (x >> 16)) & 0x1f00000000ffffull;
    x = (x ^ (x >> 32)) & 0x1fffff;
    return x;
  }

  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();
  double leaf_size_ = 0.0;
  int depth_ = 0;
  OctreeLeaves leaves_;
  std::size_t build_bytes_ = 0;  // peak memory of the build, beyond the leaves
};

}  // namespace dentmark::detect
