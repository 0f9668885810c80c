#include "leaf_sums.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <new>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace dentmark::detect::detail {
namespace {

// Why not sort: scanners deliver triangles in sensor order, but a merged or re-meshed
// scan comes in any order, and sorting 10 M keys and then gathering per-triangle sums in
// sorted order costs two random passes over memory. Instead one pass files each
// triangle's contribution under its coarse bucket (8^kBucketLevels cells of the octree)
// in chains of small chunks, and each bucket, tens of thousands of records that fit in
// the cache, is summed through a small hash table on the remaining key bits. A leaf's
// triangles are summed in an "open leaf" (a small direct-mapped table) before they are
// filed; in sensor order they come back row after row to their open leaf, so an ordered
// scan files about one record per leaf (1.25 M for 8.9 M triangles). Tried and measured
// slower: one hash table of leaves shared by the threads instead of records (0.37 -> 0.51 s
// in sensor order, no gain in random order: its random slot updates cost what the
// records' streaming does).
constexpr int kBucketLevels = 4;   // 4 096 buckets: their chain tails stay in L1/L2
constexpr int kChunkRecords = 62;  // a chunk is ~2.2 KB
constexpr int kPrefetch = 24;      // triangles ahead: hides the random vertex reads

struct Record {         // 36 bytes: the sums of some triangles in one leaf
  std::uint32_t cell;   // key bits below the bucket
  std::uint32_t count;  // triangles
  float area;           // Σ a_i
  float an[3];          // Σ a_i N_i
  float ac[3];          // Σ a_i (c_i − leaf corner): small numbers keep float precision
};

// A leaf being summed in pass 1, before it is filed as a record. 8 192 of them (320 KB)
// stay in a core's L2.
constexpr int kOpenLeafBits = 13;
constexpr std::size_t kOpenLeaves = std::size_t{1} << kOpenLeafBits;
struct OpenLeaf {
  std::uint64_t key = ~0ull;
  std::uint32_t count = 0;
  float area = 0.0f;
  float an[3] = {0, 0, 0};
  float ac[3] = {0, 0, 0};
};

struct Chunk {
  Chunk* next = nullptr;
  std::uint32_t size = 0;
  Record records[kChunkRecords];
};

// One thread's chunks: bucket chains and the storage behind them.
class ChunkStore {
 public:
  explicit ChunkStore(std::size_t buckets) : head_(buckets, nullptr), tail_(buckets) {}

  Record& append(std::size_t bucket) {
    Tail& t = tail_[bucket];
    if (!t.chunk || t.chunk->size == kChunkRecords) {
      Chunk* fresh = allocate();
      (t.chunk ? t.chunk->next : head_[bucket]) = fresh;
      t.chunk = fresh;
    }
    ++t.records;
    return t.chunk->records[t.chunk->size++];
  }
  const Chunk* head(std::size_t bucket) const { return head_[bucket]; }
  std::uint64_t records(std::size_t bucket) const { return tail_[bucket].records; }

 private:
  // Chunks come from 8 MB blocks, uninitialised until used (no zeroing pass; not huge
  // pages either: under defrag=madvise a huge-page fault may compact memory for 100s of ms).
  Chunk* allocate() {
    if (blocks_.empty() || used_ == kBlockChunks) {
      void* p = std::malloc(kBlockChunks * sizeof(Chunk));
      if (!p) throw std::bad_alloc();
      blocks_.emplace_back(static_cast<Chunk*>(p));
      used_ = 0;
    }
    return new (&blocks_.back().get()[used_++]) Chunk;
  }
  struct Free {
    void operator()(Chunk* p) const { std::free(p); }
  };
  static constexpr std::size_t kBlockChunks = (std::size_t{8} << 20) / sizeof(Chunk);
  struct Tail {
    Chunk* chunk = nullptr;
    std::uint64_t records = 0;
  };
  std::vector<Chunk*> head_;
  std::vector<Tail> tail_;
  std::vector<std::unique_ptr<Chunk, Free>> blocks_;
  std::size_t used_ = 0;
};

// Sums one bucket's records (from every thread's chain) into leaves, in Morton order.
class BucketSummer {
 public:
  void sum(const std::vector<const Chunk*>& chains, std::uint64_t records_hint, std::uint64_t bucket,
           int low_bits, const LeafGrid& grid, std::vector<OctreeLeaf>& out) {
    std::size_t size = 16;
    while (size < 2 * records_hint) size <<= 1;
    int shift = 32;
    for (std::size_t s = size; s > 1; s >>= 1) --shift;
    slots_.assign(size, -1);
    for (const Chunk* c : chains)
      for (; c; c = c->next)
        for (std::uint32_t i = 0; i < c->size; ++i) {
          const Record& r = c->records[i];
          std::size_t h = static_cast<std::uint32_t>(r.cell * 0x9E3779B1u) >> shift;
          while (slots_[h] >= 0 && sums_[static_cast<std::size_t>(slots_[h])].cell != r.cell)
            h = (h + 1) & (size - 1);
          if (slots_[h] < 0) {
            slots_[h] = static_cast<std::int32_t>(sums_.size());
            sums_.push_back(Record{r.cell, 0, 0.0f, {0, 0, 0}, {0, 0, 0}});
          }
          Record& l = sums_[static_cast<std::size_t>(slots_[h])];
          l.count += r.count;
          l.area += r.area;
          for (int a = 0; a < 3; ++a) l.an[a] += r.an[a], l.ac[a] += r.ac[a];
        }
    order_.resize(sums_.size());
    for (std::size_t i = 0; i < order_.size(); ++i) order_[i] = static_cast<std::uint32_t>(i);
    std::sort(order_.begin(), order_.end(),
              [&](std::uint32_t a, std::uint32_t b) { return sums_[a].cell < sums_[b].cell; });
    const float half = 0.5f / grid.inv_leaf;
    for (auto i : order_) {
      const Record& r = sums_[i];
      OctreeLeaf& l = out.emplace_back();
      l.key = bucket << low_bits | r.cell;
      l.count = r.count;
      l.area = r.area;
      l.sum_an = Eigen::Vector3f(r.an[0], r.an[1], r.an[2]);
      const Eigen::Vector3f offset =
          r.area > 0.0f ? Eigen::Vector3f(Eigen::Vector3f(r.ac[0], r.ac[1], r.ac[2]) / r.area)
                        : Eigen::Vector3f::Constant(half);
      l.centroid = grid.corner(l.key) + offset;
    }
    sums_.clear();
  }

 private:
  std::vector<std::int32_t> slots_;
  std::vector<Record> sums_;  // one per leaf, in order of first appearance
  std::vector<std::uint32_t> order_;
};

int thread_count() {
#ifdef _OPENMP
  return std::max(1, omp_get_max_threads());
#else
  return 1;
#endif
}

int thread_id() {
#ifdef _OPENMP
  return omp_get_thread_num();
#else
  return 0;
#endif
}

}  // namespace

std::vector<OctreeLeaf> accumulate_leaves(const ingest::MeshView& mesh, const LeafGrid& grid,
                                          std::size_t* record_bytes) {
  const std::size_t n = mesh.triangle_count();
  // At least depth - 10 bucket levels, so that a record's cell (the bits below) fits 32 bits.
  const int bucket_levels = std::max(std::min(grid.depth, kBucketLevels), grid.depth - 10);
  const int low_bits = 3 * (grid.depth - bucket_levels);
  const std::size_t buckets = std::size_t{1} << (3 * bucket_levels);
  const int threads = thread_count();
  std::vector<std::unique_ptr<ChunkStore>> stores(static_cast<std::size_t>(threads));

  // Pass 1: each thread files its slice of the triangles.
#pragma omp parallel num_threads(threads)
  {
    const auto t = static_cast<std::size_t>(thread_id());
    const std::size_t b = n * t / static_cast<std::size_t>(threads),
                      e = n * (t + 1) / static_cast<std::size_t>(threads);
    stores[t] = std::make_unique<ChunkStore>(buckets);
    ChunkStore& store = *stores[t];
    const std::uint64_t low_mask = (std::uint64_t{1} << low_bits) - 1;
    // Open leaves, direct-mapped by key: in sensor order a leaf's triangles come back
    // row after row and meet their open leaf here, so about one record per leaf is filed.
    std::vector<OpenLeaf> open(kOpenLeaves);
    OpenLeaf* last = &open[0];
    Eigen::Vector3i last_cell(-1, -1, -1);
    Eigen::Vector3f corner = Eigen::Vector3f::Zero();
    const auto file = [&](const OpenLeaf& l) {
      Record& r = store.append(l.key >> low_bits);
      r.cell = static_cast<std::uint32_t>(l.key & low_mask);
      r.count = l.count;
      r.area = l.area;
      std::copy(l.an, l.an + 3, r.an);
      std::copy(l.ac, l.ac + 3, r.ac);
    };
    for (std::size_t i = b; i < e; ++i) {
      if (i + kPrefetch < e) {
        const auto f = mesh.triangle(i + kPrefetch);
        for (int k = 0; k < 3; ++k) __builtin_prefetch(mesh.vertex_address(f[k]));
      }
      const auto tri = mesh.triangle(i);
      const Eigen::Vector3f va = mesh.vertex(tri[0]), vb = mesh.vertex(tri[1]), vc = mesh.vertex(tri[2]);
      const Eigen::Vector3f c = (va + vb + vc) * (1.0f / 3.0f);
      // Eq. (1): a_i = |v1 x v2| / 2, and a_i N_i is half the cross product itself.
      const Eigen::Vector3f an = 0.5f * (vb - va).cross(vc - va);
      const float area = an.norm();
      const Eigen::Vector3i cell = grid.cell(c);
      if (cell != last_cell || last->count == ~0u) {  // sensor order: mostly the same leaf
        const std::uint64_t key = LinearOctree::encode(cell);
        last = &open[(key * 0x9E3779B97F4A7C15ull) >> (64 - kOpenLeafBits)];
        if (last->key != key || last->count == ~0u) {
          if (last->count > 0) file(*last);
          *last = OpenLeaf{key};
        }
        last_cell = cell, corner = grid.corner(cell);
      }
      // Centroids relative to the cell's corner: small numbers keep float precision.
      const Eigen::Vector3f ac = area * (c - corner);
      OpenLeaf& l = *last;
      l.count += 1;
      l.area += area;
      for (int a = 0; a < 3; ++a) l.an[a] += an[a], l.ac[a] += ac[a];
    }
    for (const OpenLeaf& l : open)
      if (l.count > 0) file(l);
  }

  // Pass 2: buckets in key order, split between threads by record count; each thread's
  // leaves come out sorted and the parts are concatenated in thread order.
  std::vector<std::uint64_t> start(buckets + 1, 0);
  for (std::size_t k = 0; k < buckets; ++k) {
    std::uint64_t c = 0;
    for (const auto& s : stores) c += s->records(k);
    start[k + 1] = start[k] + c;
  }
  const std::uint64_t records = start[buckets];
  if (record_bytes) *record_bytes = static_cast<std::size_t>(records) * sizeof(Record);
  std::vector<std::vector<OctreeLeaf>> parts(static_cast<std::size_t>(threads));
#pragma omp parallel num_threads(threads)
  {
    const auto t = static_cast<std::size_t>(thread_id());
    const auto nt = static_cast<std::size_t>(threads);
    const auto first_bucket = [&](std::size_t slice) {
      return static_cast<std::size_t>(std::lower_bound(start.begin(), start.end() - 1, records * slice / nt) -
                                      start.begin());
    };
    const std::size_t kb = first_bucket(t), ke = t + 1 == nt ? buckets : first_bucket(t + 1);
    // A leaf holds at least one record, so this never regrows; the capacity beyond the
    // leaves is address space only, never touched. Thread 0's part receives the others.
    auto& out = parts[t];
    out.reserve(t == 0 ? records : start[ke] - start[kb]);
    BucketSummer summer;
    std::vector<const Chunk*> chains(stores.size());
    for (std::size_t k = kb; k < ke; ++k) {
      if (start[k + 1] == start[k]) continue;
      for (std::size_t s = 0; s < stores.size(); ++s) chains[s] = stores[s]->head(k);
      summer.sum(chains, start[k + 1] - start[k], k, low_bits, grid, out);
    }
  }
  stores.clear();
  std::vector<OctreeLeaf> leaves = std::move(parts[0]);
  for (std::size_t p = 1; p < parts.size(); ++p)
    leaves.insert(leaves.end(), parts[p].begin(), parts[p].end());
  return leaves;
}

}  // namespace dentmark::detect::detail
