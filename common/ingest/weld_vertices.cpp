// Welding coincident vertices: one pass over them with an open-addressing hash table of
// the vertices kept so far, keyed by their exact coordinates (-0 as 0).
#include <bit>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include "dentmark/common/ingest/detail/readers.h"

namespace dentmark::ingest::detail {
namespace {

constexpr std::uint32_t kEmpty = std::numeric_limits<std::uint32_t>::max();

struct Bits {
  std::uint32_t x, y, z;
  bool operator==(const Bits&) const = default;
};

Bits bits_of(const Eigen::Vector3f& v) {
  Bits b;
  const float x = v.x() + 0.0f, y = v.y() + 0.0f, z = v.z() + 0.0f;  // -0 -> +0
  std::memcpy(&b.x, &x, 4), std::memcpy(&b.y, &y, 4), std::memcpy(&b.z, &z, 4);
  return b;
}

std::uint64_t hash(const Bits& b) {
  std::uint64_t h = (static_cast<std::uint64_t>(b.x) << 32 | b.y) * 0x9E3779B97F4A7C15ull;
  h ^= (h >> 29) ^ (static_cast<std::uint64_t>(b.z) * 0xC2B2AE3D27D4EB4Full);
  return h ^ (h >> 32);
}

}  // namespace

void weld_vertices(Mesh& mesh) {
  const std::size_t n = mesh.vertices.size();
  if (n == 0) return;
  const std::size_t mask = std::bit_ceil(2 * n) - 1;
  std::vector<std::uint32_t> slot(mask + 1, kEmpty);  // a kept vertex's new index
  std::vector<Bits> kept_bits;
  std::vector<std::uint32_t> renumber(n);
  std::size_t kept = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Bits b = bits_of(mesh.vertices[i]);
    std::size_t h = hash(b) & mask;
    while (slot[h] != kEmpty && !(kept_bits[slot[h]] == b)) h = (h + 1) & mask;
    if (slot[h] == kEmpty) {
      slot[h] = static_cast<std::uint32_t>(kept);
      kept_bits.push_back(b);
      mesh.vertices[kept++] = mesh.vertices[i];  // kept <= i: the vertex is read before it is overwritten
    }
    renumber[i] = slot[h];
  }
  mesh.vertices.resize(kept);
  mesh.vertices.shrink_to_fit();
  for (auto& t : mesh.triangles)
    for (auto& v : t) v = renumber[v];
}

}  // namespace dentmark::ingest::detail
