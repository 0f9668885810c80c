#include "leaf_sums.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>
#include <utility>

#include "hot_loop.h"
#include "threads.h"

namespace dentmark::detect::detail {
namespace {

// Why not sort: scanners deliver triangles in sensor order, but a merged or re-meshed
// scan comes in any order, and sorting 10 M keys and then gathering per-triangle sums in
// sorted order costs two random passes over memory. Instead one pass files each
// triangle's contribution under its coarse bucket (8^kBucketLevels cells of the octree)
// in chains of small chunks, and each bucket is summed octant by octant through hash
// tables on the remaining key bits that stay in the cache.
//
// In sensor order a leaf's triangles come back row after row, so they are first summed
// in an "open leaf" (a small direct-mapped table) and about one record per leaf is filed
// (1.25 M for 8.9 M triangles). In random order the open leaves are never met again and
// only cost a cache miss each: blocks whose triangles mostly miss them switch to filing
// every triangle directly, and every 16th block looks again.
//
// The triangles are taken in slices, each by whichever thread is free (threads run at
// uneven speeds on a shared machine: a fixed half each left one waiting 40 ms). A slice's
// records depend only on its triangles (its open leaves start empty and are filed at its
// end), and pass 2 sums each bucket's records in slice order, so the leaves are the same
// to the last bit whichever thread took which slice, and with any number of threads.
//
// Tried and measured slower: one hash table of leaves shared by the threads instead of
// records (0.37 -> 0.51 s in sensor order, no gain in random order: its random slot
// updates cost what the records' streaming does).
constexpr int kBucketLevels = 4;           // 4 096 buckets: their chain tails stay in L1/L2
constexpr std::size_t kChunkBytes = 2200;  // a chunk of records
constexpr int kPrefetch = 48;              // triangles ahead: hides the random vertex reads
constexpr int kBatch = 64;                 // triangles whose geometry is computed together
constexpr std::size_t kModeBlock = 16384;  // triangles per open/direct decision
constexpr int kRecheckEvery = 16;          // direct blocks between two open ones

// The sums of some triangles in one leaf (an open leaf's), 28 bytes. The centroid is kept
// as the area-weighted mean position in the leaf, in 1/65536 of its edge (15 nm at 1 mm).
struct Record {
  std::uint32_t cell;  // the leaf's Morton code in its bucket: its key's low bits (at most 30)
  float area;          // Σ a_i
  float an[3];         // Σ a_i N_i
  std::uint16_t mean[3];
  std::uint16_t count;  // triangles (an open leaf is filed before it reaches 65 535)
};
static_assert(sizeof(Record) == 28);

// One triangle filed directly, 12 bytes: in random order one is filed per triangle (8.9 M
// of them), all of it fresh memory, which is what a run pays for most on a VM.
//  - pos: its centroid in the bucket's cube in 16-bit fixed point per axis, the leaf's
//    cell in the top bits and the position in the leaf below (1/512 of a leaf at depth
//    11, 2 um at 1 mm; 1/64 at the deepest tree, depth 16).
//  - an: a_i N_i as three 13-bit mantissas sharing the exponent of the largest (block
//    floating point, relative error <= 2^-12 of |a_i N_i|); its area is |a_i N_i|.
struct Single {
  std::uint16_t pos[3];
  std::uint16_t an[3];
};
static_assert(sizeof(Single) == 12);

// a_i N_i <-> 48 bits: exponent byte, then the mantissas. Below 2^-115 m² it is zero.
constexpr std::uint32_t kMinExponent = 12;
void pack_an(const float an[3], std::uint16_t out[3]) {
  const float largest = std::max({std::abs(an[0]), std::abs(an[1]), std::abs(an[2])});
  const std::uint32_t e = std::bit_cast<std::uint32_t>(largest) >> 23;  // biased exponent
  std::uint64_t w = 0;
  if (e >= kMinExponent) {
    const float scale = std::bit_cast<float>((265u - e) << 23);  // largest * scale in [2^11, 2^12)
    w = e;
    for (int a = 0; a < 3; ++a) {
      const long q = std::clamp(std::lrint(an[a] * scale), -4095l, 4095l);
      w |= (static_cast<std::uint64_t>(q) & 0x1fff) << (8 + 13 * a);
    }
  }
  for (int k = 0; k < 3; ++k) out[k] = static_cast<std::uint16_t>(w >> (16 * k));
}
void unpack_an(const std::uint16_t in[3], float an[3]) {
  const std::uint64_t w = in[0] | std::uint64_t{in[1]} << 16 | std::uint64_t{in[2]} << 32;
  const auto e = static_cast<std::uint32_t>(w & 0xff);
  const float unit = e >= kMinExponent ? std::bit_cast<float>((e - 11) << 23) : 0.0f;
  for (int a = 0; a < 3; ++a) {
    const auto bits = static_cast<std::uint32_t>(w >> (8 + 13 * a)) << 19;
    an[a] = static_cast<float>(static_cast<std::int32_t>(bits) >> 19) * unit;
  }
}

// A cell's place in its bucket's cube and a position in the cell, one 16-bit code per
// axis: the cell's `levels` bits on top, the position in the cell below.
struct PositionCode {
  explicit PositionCode(int levels)
      : cell_mask((1u << levels) - 1), frac_bits(16 - levels), frac_scale(std::ldexp(1.0f, frac_bits)) {}
  // cell: the leaf's coordinate on the axis; f: the position in it (edge = 1, clamped).
  std::uint16_t encode(std::int32_t cell, float f) const {
    const int frac = std::clamp(static_cast<int>(f * frac_scale), 0, (1 << frac_bits) - 1);
    return static_cast<std::uint16_t>((static_cast<std::uint32_t>(cell) & cell_mask) << frac_bits |
                                      static_cast<std::uint32_t>(frac));
  }
  std::uint32_t cell(std::uint16_t code) const { return code >> frac_bits; }
  float position(std::uint16_t code) const {  // the middle of the code's step
    return (static_cast<float>(code & ((1u << frac_bits) - 1)) + 0.5f) / frac_scale;
  }

  const std::uint32_t cell_mask;
  const int frac_bits;
  const float frac_scale;
};

std::uint16_t quantize(float f) {  // position in the leaf, [0, 1] -> 1/65536 steps
  return static_cast<std::uint16_t>(std::clamp(f * 65536.0f + 0.5f, 0.0f, 65535.0f));
}

// A leaf being summed in pass 1, before it is filed as a record. 8 192 of them (320 KB)
// stay in a core's L2.
constexpr int kOpenLeafBits = 13;
constexpr std::size_t kOpenLeaves = std::size_t{1} << kOpenLeafBits;
struct OpenLeaf {
  std::uint64_t cell = ~0ull;  // TriangleBatch::pack(); never a cell's (bit 63)
  std::uint32_t count = 0;
  float area = 0.0f;
  float an[3] = {0, 0, 0};
  float af[3] = {0, 0, 0};  // Σ a_i f_i, f_i the centroid's position in the leaf (edge = 1)
};

// Triangles per slice: a function of the triangle count alone (the leaves must not depend
// on the thread count); ~32 slices, but not so small that filing their last open leaves
// and starting fresh chunks costs, nor so large that a thread waits long for another.
std::size_t slice_size(std::size_t triangles) {
  return std::clamp<std::size_t>(triangles / 32, std::size_t{1} << 16, std::size_t{1} << 20);
}

template <typename R>
struct Chunk {
  static constexpr std::uint32_t kCapacity = (kChunkBytes - 16) / sizeof(R);
  Chunk* next = nullptr;
  std::uint32_t size = 0;
  std::uint32_t slice = 0;  // a chunk holds records of one slice
  R records[kCapacity];
};

// One thread's chunks of one kind of record: bucket chains and the storage behind them.
template <typename R>
class ChunkStore {
 public:
  explicit ChunkStore(std::size_t buckets) : head_(buckets, nullptr), tail_(buckets) {}

  // Records appended from now on belong to this slice (slices come in increasing order).
  void begin_slice(std::uint32_t slice) { slice_ = slice; }

  R& append(std::size_t bucket) {
    Tail& t = tail_[bucket];
    if (!t.chunk || t.chunk->size == Chunk<R>::kCapacity || t.chunk->slice != slice_) {
      Chunk<R>* fresh = allocate();
      (t.chunk ? t.chunk->next : head_[bucket]) = fresh;
      t.chunk = fresh;
    }
    ++t.records;
    return t.chunk->records[t.chunk->size++];
  }
  const Chunk<R>* head(std::size_t bucket) const { return head_[bucket]; }
  std::uint64_t records(std::size_t bucket) const { return tail_[bucket].records; }
  std::uint64_t records() const {
    std::uint64_t n = 0;
    for (const Tail& t : tail_) n += t.records;
    return n;
  }

 private:
  // Chunks come from 8 MB blocks, uninitialised until used (no zeroing pass).
  Chunk<R>* allocate() {
    if (blocks_.empty() || used_ == kBlockChunks) {
      void* p = std::malloc(kBlockChunks * sizeof(Chunk<R>));
      if (!p) throw std::bad_alloc();
      blocks_.emplace_back(static_cast<Chunk<R>*>(p));
      used_ = 0;
    }
    auto* chunk = new (&blocks_.back().get()[used_++]) Chunk<R>;
    chunk->slice = slice_;
    return chunk;
  }
  struct Free {
    void operator()(Chunk<R>* p) const { std::free(p); }
  };
  static constexpr std::size_t kBlockChunks = (std::size_t{8} << 20) / sizeof(Chunk<R>);
  struct Tail {
    Chunk<R>* chunk = nullptr;
    std::uint64_t records = 0;
  };
  std::vector<Chunk<R>*> head_;
  std::vector<Tail> tail_;
  std::vector<std::unique_ptr<Chunk<R>, Free>> blocks_;
  std::size_t used_ = 0;
  std::uint32_t slice_ = 0;
};

// What one thread files in pass 1.
struct ThreadRecords {
  explicit ThreadRecords(std::size_t buckets) : sums(buckets), singles(buckets) {}
  void begin_slice(std::uint32_t slice) { sums.begin_slice(slice), singles.begin_slice(slice); }
  ChunkStore<Record> sums;
  ChunkStore<Single> singles;
};

// The geometry of kBatch triangles, computed together (the arithmetic vectorises; the
// vertex reads are gathers).
struct TriangleBatch {
  float v[3][3][kBatch];  // vertex, axis, triangle
  float an[3][kBatch];    // a_i N_i
  float area[kBatch];     // a_i
  float f[3][kBatch];     // centroid's position in its cell (edge = 1)
  std::int32_t cell[3][kBatch];
  std::uint64_t packed[kBatch];  // the cell as one number (pack(), to compare)

  // A cell as one number, x | y << 21 | z << 42, and its Morton key.
  static constexpr int kAxisBits = 21;
  static std::uint64_t pack(std::uint64_t x, std::uint64_t y, std::uint64_t z) {
    return x | y << kAxisBits | z << 2 * kAxisBits;
  }
  static std::uint64_t key_of_packed(std::uint64_t p) {
    constexpr std::uint64_t kAxis = (std::uint64_t{1} << kAxisBits) - 1;
    return LinearOctree::encode({static_cast<int>(p & kAxis), static_cast<int>(p >> kAxisBits & kAxis),
                                 static_cast<int>(p >> 2 * kAxisBits & kAxis)});
  }

  // Stored coordinates to metres, all at once.
  void scale(float s) {
    for (auto& vertex : v)
      for (auto& axis : vertex)
        for (float& x : axis) x *= s;
  }

  DENTMARK_HOT_LOOP void compute(const LeafGrid& grid) {
    const float cells_max = static_cast<float>((1 << grid.depth) - 1);
#pragma omp simd
    for (int j = 0; j < kBatch; ++j) {
      const float e1[3] = {v[1][0][j] - v[0][0][j], v[1][1][j] - v[0][1][j], v[1][2][j] - v[0][2][j]};
      const float e2[3] = {v[2][0][j] - v[0][0][j], v[2][1][j] - v[0][1][j], v[2][2][j] - v[0][2][j]};
      // Eq. (1): a_i = |v1 x v2| / 2, and a_i N_i is half the cross product itself.
      const float nx = 0.5f * (e1[1] * e2[2] - e1[2] * e2[1]);
      const float ny = 0.5f * (e1[2] * e2[0] - e1[0] * e2[2]);
      const float nz = 0.5f * (e1[0] * e2[1] - e1[1] * e2[0]);
      an[0][j] = nx, an[1][j] = ny, an[2][j] = nz;
      area[j] = std::sqrt(nx * nx + ny * ny + nz * nz);
      locate(grid, cells_max, 0, j), locate(grid, cells_max, 1, j), locate(grid, cells_max, 2, j);
      packed[j] = pack(static_cast<std::uint64_t>(cell[0][j]), static_cast<std::uint64_t>(cell[1][j]),
                       static_cast<std::uint64_t>(cell[2][j]));
    }
  }
  // The centroid's cell along axis a, as LeafGrid::cell to the last bit (the same
  // triangle lands in the same leaf), and its position in the cell.
  [[gnu::always_inline]] void locate(const LeafGrid& grid, float cells_max, int a, int j) {
    const float c = (v[0][a][j] + v[1][a][j] + v[2][a][j]) * (1.0f / 3.0f);
    const float g = (c - grid.origin[a]) * grid.inv_leaf;
    const auto q = static_cast<std::int32_t>(std::min(std::max(g, 0.0f), cells_max));
    cell[a][j] = q;
    f[a][j] = g - static_cast<float>(q);
  }
};

// Sums one bucket's records (from every thread's chains) into leaves, in Morton order.
class BucketSummer {
 public:
  explicit BucketSummer(const PositionCode& code) : code_(code) {}

  // Sums the bucket; returns the number of leaves that write() will write.
  //
  // In random order a door's bucket holds ~90 000 singles and ~11 000 leaves, whose sums
  // and hash slots overflow a core's L2: nearly every add missed it (pass 2 took 0.3-0.45
  // s). So the records are first dealt into the bucket's eight octants (a stable copy,
  // which streams) and each octant, an eighth of the leaves, is summed through a table of
  // its own. A leaf lies in one octant and its records keep their order (sums before
  // singles, each in slice order), so its sums are the same to the last bit.
  std::size_t sum(const std::vector<std::unique_ptr<ThreadRecords>>& threads, std::size_t bucket) {
    for (auto& o : octant_sums_) o.clear();
    for (auto& o : octant_singles_) o.clear();
    for (const Chunk<Record>* c : in_slice_order(threads, &ThreadRecords::sums, bucket, record_chunks_))
      for (std::uint32_t i = 0; i < c->size; ++i)
        octant_sums_[octant(c->records[i].cell)].push_back(c->records[i]);
    for (const Chunk<Single>* c : in_slice_order(threads, &ThreadRecords::singles, bucket, single_chunks_))
      for (std::uint32_t i = 0; i < c->size; ++i)
        octant_singles_[octant(cell_of(c->records[i]))].push_back(c->records[i]);
    sums_.clear();
    for (int o = 0; o < 8; ++o) {
      start_table(octant_sums_[o].size() + octant_singles_[o].size());
      for (const Record& r : octant_sums_[o]) {
        const float mean[3] = {r.mean[0] * (1.0f / 65536.0f), r.mean[1] * (1.0f / 65536.0f),
                               r.mean[2] * (1.0f / 65536.0f)};
        add(r.cell, r.count, r.area, r.an, mean);
      }
      for (const Single& r : octant_singles_[o]) {
        float an[3], mean[3];
        unpack_an(r.an, an);
        for (int a = 0; a < 3; ++a) mean[a] = code_.position(r.pos[a]);
        add(cell_of(r), 1, std::sqrt(an[0] * an[0] + an[1] * an[1] + an[2] * an[2]), an, mean);
      }
    }
    order_.resize(sums_.size());
    for (std::size_t i = 0; i < order_.size(); ++i) order_[i] = std::uint64_t{sums_[i].cell} << 32 | i;
    sort_by_morton();
    return sums_.size();
  }

  // Writes the summed bucket's leaves from `out` on.
  void write(std::size_t bucket, int low_bits, const LeafGrid& grid, OctreeLeaf* out) const {
    const float leaf = 1.0f / grid.inv_leaf;
    for (const std::uint64_t o : order_) {
      const Sum& r = sums_[static_cast<std::uint32_t>(o)];
      OctreeLeaf& l = *out++;
      l.key = bucket << low_bits | o >> 32;
      l.count = r.count;
      l.area = r.area;
      l.sum_an = Eigen::Vector3f(r.an[0], r.an[1], r.an[2]);
      const Eigen::Vector3f mean = r.area > 0.0f
                                       ? Eigen::Vector3f(Eigen::Vector3f(r.af[0], r.af[1], r.af[2]) / r.area)
                                       : Eigen::Vector3f::Constant(0.5f);
      l.centroid = grid.corner(l.key) + mean * leaf;
    }
  }

 private:
  // order_ by its Morton codes (distinct: one per leaf), least significant digit first:
  // two or three passes of at most 11 bits over a bucket's thousands of leaves, a third
  // of the time std::sort took.
  void sort_by_morton() {
    if (order_.size() < 64) {  // (64 distinct codes or more have 6 bits or more)
      std::sort(order_.begin(), order_.end());
      return;
    }
    const int bits = 3 * std::popcount(code_.cell_mask);
    const int passes = (bits + 10) / 11, digit = (bits + passes - 1) / passes;
    const std::uint64_t mask = (std::uint64_t{1} << digit) - 1;
    spare_.resize(order_.size());
    for (int p = 0; p < passes; ++p) {
      const int shift = 32 + p * digit;
      histogram_.assign(std::size_t{1} << digit, 0);
      for (const std::uint64_t o : order_) ++histogram_[o >> shift & mask];
      std::uint32_t sum = 0;
      for (std::uint32_t& h : histogram_) sum += std::exchange(h, sum);
      for (const std::uint64_t o : order_) spare_[histogram_[o >> shift & mask]++] = o;
      order_.swap(spare_);
    }
  }

  // The bucket's chunks of one kind from every thread, in slice order: float sums then
  // come out the same whichever thread filed which slice. A thread's chain is in slice
  // order already, and a slice is one thread's, so a stable merge by slice is enough.
  template <typename R>
  static const std::vector<const Chunk<R>*>& in_slice_order(
      const std::vector<std::unique_ptr<ThreadRecords>>& threads, ChunkStore<R> ThreadRecords::*kind,
      std::size_t bucket, std::vector<const Chunk<R>*>& chunks) {
    chunks.clear();
    for (const auto& t : threads)
      for (const Chunk<R>* c = ((*t).*kind).head(bucket); c; c = c->next) chunks.push_back(c);
    if (threads.size() > 1)
      std::stable_sort(chunks.begin(), chunks.end(),
                       [](const Chunk<R>* a, const Chunk<R>* b) { return a->slice < b->slice; });
    return chunks;
  }

  struct Sum {
    std::uint32_t cell;
    std::uint32_t count = 0;
    float area = 0.0f;
    float an[3] = {0, 0, 0};
    float af[3] = {0, 0, 0};
  };
  // A single's cell as Record::cell.
  std::uint32_t cell_of(const Single& r) const {
    return static_cast<std::uint32_t>(
        LinearOctree::encode({static_cast<int>(code_.cell(r.pos[0])), static_cast<int>(code_.cell(r.pos[1])),
                              static_cast<int>(code_.cell(r.pos[2]))}));
  }
  // The octant of the bucket's cube holding a cell: its code's top three bits.
  std::uint32_t octant(std::uint32_t cell) const { return cell >> octant_shift_ & 7; }
  // An empty hash table for up to `records` leaves, at most half full.
  void start_table(std::size_t records) {
    std::size_t size = 16;
    while (size < 2 * records) size <<= 1;
    shift_ = 32;
    for (std::size_t s = size; s > 1; s >>= 1) --shift_;
    slots_.assign(size, -1);
  }
  // mean: the triangles' mean position in the leaf (edge = 1).
  void add(std::uint32_t cell, std::uint32_t count, float area, const float an[3], const float mean[3]) {
    const std::size_t mask = slots_.size() - 1;
    std::size_t h = static_cast<std::uint32_t>(cell * 0x9E3779B1u) >> shift_;
    while (slots_[h] >= 0 && sums_[static_cast<std::size_t>(slots_[h])].cell != cell) h = (h + 1) & mask;
    if (slots_[h] < 0) {
      slots_[h] = static_cast<std::int32_t>(sums_.size());
      sums_.emplace_back().cell = cell;  // (in place: Sum{cell} went through the stack)
    }
    Sum& l = sums_[static_cast<std::size_t>(slots_[h])];
    l.count += count;
    l.area += area;
    for (int a = 0; a < 3; ++a) l.an[a] += an[a], l.af[a] += area * mean[a];
  }

  const PositionCode code_;
  const int octant_shift_ = std::max(3 * std::popcount(code_.cell_mask) - 3, 0);
  std::vector<Record> octant_sums_[8];
  std::vector<Single> octant_singles_[8];
  int shift_ = 32;
  std::vector<std::int32_t> slots_;
  std::vector<Sum> sums_;                 // one per leaf, in order of first appearance
  std::vector<std::uint64_t> order_;      // Morton code in the bucket << 32 | index into sums_
  std::vector<std::uint64_t> spare_;      // sort_by_morton's other buffer
  std::vector<std::uint32_t> histogram_;  // and its digit counts
  std::vector<const Chunk<Record>*> record_chunks_;
  std::vector<const Chunk<Single>*> single_chunks_;
};

// Pass 1 for one thread: files the slices of triangles it takes, one after another.
class LeafFiler {
 public:
  LeafFiler(const LeafGrid& grid, int low_bits, ThreadRecords& store)
      : grid_(grid), low_bits_(low_bits), code_(low_bits / 3), store_(store) {}

  // Files the triangles [b, e) of one slice; its open leaves start empty and are filed at
  // its end, so what it files depends on nothing else.
  void run_slice(const ingest::MeshView& mesh, std::uint32_t slice, std::size_t b, std::size_t e) {
    store_.begin_slice(slice);
    direct_ = false;
    TriangleBatch batch;
    int blocks_direct = 0;  // direct blocks since the last open one
    for (std::size_t block = b; block < e; block += kModeBlock) {
      const std::size_t block_end = std::min(e, block + kModeBlock);
      misses_ = 0;
      for (std::size_t i = block; i < block_end; i += kBatch) {
        const int m = static_cast<int>(std::min<std::size_t>(kBatch, block_end - i));
        gather(mesh, i, m, e, batch);
        batch.compute(grid_);
        if (direct_)
          file_each(batch, m);
        else
          sum_open(batch, m);
      }
      if (direct_) {
        if (++blocks_direct == kRecheckEvery) direct_ = false, blocks_direct = 0;
      } else {
        direct_ = 2 * misses_ > block_end - block;
      }
    }
    for (OpenLeaf& l : open_) {
      if (l.count > 0) file(l);
      l = OpenLeaf{};
    }
  }

 private:
  static void gather(const ingest::MeshView& mesh, std::size_t first, int m, std::size_t end,
                     TriangleBatch& batch) {
    for (int j = 0; j < m; ++j) {
      const std::size_t i = first + static_cast<std::size_t>(j);
      if (i + kPrefetch < end) {
        const auto f = mesh.triangle(i + kPrefetch);
        for (int k = 0; k < 3; ++k) __builtin_prefetch(mesh.vertex_address(f[k]));
      }
      const auto tri = mesh.triangle(i);
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3f p = mesh.stored_vertex(tri[k]);
        for (int a = 0; a < 3; ++a) batch.v[k][a][j] = p[a];
      }
    }
    for (int j = m; j < kBatch; ++j)  // the tail repeats the last triangle; never summed
      for (int k = 0; k < 3; ++k)
        for (int a = 0; a < 3; ++a) batch.v[k][a][j] = batch.v[k][a][m - 1];
    if (const float s = mesh.scale(); s != 1.0f) batch.scale(s);  // (as MeshView::vertex)
  }

  std::uint64_t key_of(const TriangleBatch& t, int j) const {
    return LinearOctree::encode({t.cell[0][j], t.cell[1][j], t.cell[2][j]});
  }

  // Sensor order: a leaf's triangles meet their open leaf. Each triangle goes straight to
  // its slot, found from its cell without a Morton key (made only when a leaf is filed).
  // The one branch is taken about once a record, so it is predicted: tracking the last
  // two leaves instead and carrying the current one's sums in registers branched at
  // every change of leaf, every few triangles, and pass 1 took 85 ms, not 55.
  DENTMARK_HOT_LOOP void sum_open(const TriangleBatch& t, int m) {
    for (int j = 0; j < m; ++j) {
      const std::uint64_t cell = t.packed[j];
      OpenLeaf& l = open_[(cell * 0x9E3779B97F4A7C15ull) >> (64 - kOpenLeafBits)];
      if (l.cell != cell || l.count == 0xffff) [[unlikely]] {
        ++misses_;
        if (l.count > 0) file(l);
        l = OpenLeaf{cell};
      }
      const float a = t.area[j];
      l.count += 1;
      l.area += a;
      for (int k = 0; k < 3; ++k) l.an[k] += t.an[k][j], l.af[k] += a * t.f[k][j];
    }
  }

  // Random order: one record per triangle.
  DENTMARK_HOT_LOOP void file_each(const TriangleBatch& t, int m) {
    for (int j = 0; j < m; ++j) {
      Single& r = store_.singles.append(key_of(t, j) >> low_bits_);
      const float an[3] = {t.an[0][j], t.an[1][j], t.an[2][j]};
      pack_an(an, r.an);
      for (int a = 0; a < 3; ++a) r.pos[a] = code_.encode(t.cell[a][j], t.f[a][j]);
    }
  }

  void file(const OpenLeaf& l) {
    const std::uint64_t key = TriangleBatch::key_of_packed(l.cell);
    Record& r = store_.sums.append(key >> low_bits_);
    r.cell = static_cast<std::uint32_t>(key & ((std::uint64_t{1} << low_bits_) - 1));
    r.area = l.area;
    for (int k = 0; k < 3; ++k)
      r.an[k] = l.an[k], r.mean[k] = quantize(l.area > 0.0f ? l.af[k] / l.area : 0.5f);
    r.count = static_cast<std::uint16_t>(l.count);
  }

  const LeafGrid& grid_;
  const int low_bits_;
  const PositionCode code_;  // Single::pos
  ThreadRecords& store_;
  // Open leaves, direct-mapped by cell.
  std::vector<OpenLeaf> open_ = std::vector<OpenLeaf>(kOpenLeaves);
  bool direct_ = false;
  std::size_t misses_ = 0;  // leaf changes that found no open leaf, this block
};

// A share of the buckets in pass 2 not yet taken, [lo, hi): taken one at a time from
// either end, by its owner and by a thread taking it over.
class BucketRange {
 public:
  void reset(std::size_t lo, std::size_t hi) {
    range_.store(static_cast<std::uint64_t>(lo) << 32 | static_cast<std::uint64_t>(hi));
  }
  // The next bucket from the low (or high) end into k; false when none is left.
  bool take(bool from_low, std::size_t& k) {
    std::uint64_t r = range_.load(std::memory_order_relaxed);
    for (;;) {
      const std::uint64_t lo = r >> 32, hi = r & 0xffffffffu;
      if (lo >= hi) return false;
      const std::uint64_t next = from_low ? (lo + 1) << 32 | hi : lo << 32 | (hi - 1);
      if (range_.compare_exchange_weak(r, next, std::memory_order_relaxed)) {
        k = static_cast<std::size_t>(from_low ? lo : hi - 1);
        return true;
      }
    }
  }

 private:
  std::atomic<std::uint64_t> range_{0};
};

}  // namespace

namespace {

using Stores = std::vector<std::unique_ptr<ThreadRecords>>;

// Pass 1: the threads file slices of the triangles, each taking the next one left.
Stores file_triangles(const ingest::MeshView& mesh, const LeafGrid& grid, int low_bits, std::size_t buckets,
                      int threads) {
  const std::size_t n = mesh.triangle_count();
  Stores stores(static_cast<std::size_t>(threads));
  const std::size_t slice = slice_size(n), slices = (n + slice - 1) / slice;
  std::atomic<std::size_t> next_slice{0};
#pragma omp parallel num_threads(threads)
  {
    const auto t = static_cast<std::size_t>(thread_index());
    stores[t] = std::make_unique<ThreadRecords>(buckets);
    LeafFiler filer(grid, low_bits, *stores[t]);
    for (std::size_t s; (s = next_slice.fetch_add(1, std::memory_order_relaxed)) < slices;)
      filer.run_slice(mesh, static_cast<std::uint32_t>(s), s * slice, std::min(n, (s + 1) * slice));
  }
  return stores;
}

// Where each bucket's records begin, all threads' together: start[k] .. start[k + 1].
std::vector<std::uint64_t> bucket_starts(const Stores& stores, std::size_t buckets) {
  std::vector<std::uint64_t> start(buckets + 1, 0);
  for (std::size_t k = 0; k < buckets; ++k) {
    std::uint64_t c = 0;
    for (const auto& s : stores) c += s->sums.records(k) + s->singles.records(k);
    start[k + 1] = start[k] + c;
  }
  return start;
}

// A run of leaves in the block.
struct Run {
  std::size_t begin = 0, size = 0;
};

// Pass 2: buckets in key order, a share of them per thread by record count. A bucket has
// at least as many records as leaves, so a share's leaves fit in its buckets' part of a
// block sized for the records. Shares come in pairs: the first is written backwards,
// ending where the second's records begin, and the second forwards from there, so a
// pair's leaves are one run (with two threads, the whole window). The block beyond the
// window is never touched (address space only).
//
// A thread sums its own share from the end next to its partner's share; then it takes
// its partner's from the far end, in the other direction, until the two meet (threads
// run at uneven speeds on a VM: with fixed shares one waited up to 13 ms of ~40). Each
// share's leaves: its owner's run (owned) and the run taken over from it (taken_over).
struct SharedSums {
  std::vector<Run> owned, taken_over;
  std::size_t buckets_taken_over = 0;
};
SharedSums sum_buckets(const Stores& stores, const std::vector<std::uint64_t>& start, const LeafGrid& grid,
                       int low_bits, int threads, OctreeLeaf* block) {
  const std::size_t buckets = start.size() - 1;
  const std::uint64_t records = start[buckets];
  const auto nt = static_cast<std::size_t>(threads);
  std::vector<std::size_t> first(nt + 1, buckets);  // share s: buckets [first[s], first[s + 1])
  for (std::size_t s = 0; s < nt; ++s)
    first[s] = static_cast<std::size_t>(std::lower_bound(start.begin(), start.end() - 1, records * s / nt) -
                                        start.begin());
  std::vector<BucketRange> left(nt);  // each share's buckets not yet taken
  for (std::size_t s = 0; s < nt; ++s) left[s].reset(first[s], first[s + 1]);
  SharedSums out{std::vector<Run>(nt), std::vector<Run>(nt), 0};
  std::atomic<std::size_t> buckets_taken_over{0};
#pragma omp parallel num_threads(threads)
  {
    const auto t = static_cast<std::size_t>(thread_index());
    BucketSummer summer{PositionCode(low_bits / 3)};
    const auto sum_share = [&](std::size_t s, bool taking_over, Run& run) {
      // Backwards from the share's end, taking buckets from its high end; or forwards from
      // its beginning, taking them from its low end.
      const bool backwards = (s % 2 == 0) != taking_over;
      const std::size_t from = backwards ? start[first[s + 1]] : start[first[s]];
      std::size_t cursor = from;
      for (std::size_t k; left[s].take(!backwards, k);) {
        if (start[k + 1] == start[k]) continue;
        if (taking_over) buckets_taken_over.fetch_add(1, std::memory_order_relaxed);
        const std::size_t written = summer.sum(stores, k);
        if (backwards) cursor -= written;
        summer.write(k, low_bits, grid, block + cursor);
        if (!backwards) cursor += written;
      }
      run = backwards ? Run{cursor, from - cursor} : Run{from, cursor - from};
    };
    sum_share(t, false, out.owned[t]);
    if ((t ^ 1) < nt) sum_share(t ^ 1, true, out.taken_over[t ^ 1]);
  }
  out.buckets_taken_over = buckets_taken_over.load();
  return out;
}

// The shares' runs made one, in share order: the window of the block that holds the leaves.
Run join_runs(const SharedSums& sums, OctreeLeaf* block) {
  const std::size_t nt = sums.owned.size();
  // A share's runs made one: the run taken over (the imbalance, small) moved next to its
  // owner's, below it in a first share and above it in a second.
  std::vector<Run> part(nt);
  for (std::size_t s = 0; s < nt; ++s) {
    const Run &own = sums.owned[s], &over = sums.taken_over[s];
    const std::size_t to = s % 2 == 0 ? own.begin - over.size : own.begin + own.size;
    if (over.size > 0 && to != over.begin)
      std::memmove(static_cast<void*>(block + to), block + over.begin, over.size * sizeof(OctreeLeaf));
    part[s] = {s % 2 == 0 ? to : own.begin, own.size + over.size};
  }
  // More than two threads: the pairs' runs are moved together (each to a lower address).
  std::size_t total = 0;
  for (std::size_t p = 0; p < nt; ++p) {
    if (part[p].begin != part[0].begin + total)
      std::memmove(static_cast<void*>(block + part[0].begin + total), block + part[p].begin,
                   part[p].size * sizeof(OctreeLeaf));
    total += part[p].size;
  }
  return {part[0].begin, total};
}

}  // namespace

OctreeLeaves accumulate_leaves(const ingest::MeshView& mesh, const LeafGrid& grid, LeafBuildStats* stats) {
  // At least depth - 10 bucket levels: a cell in its bucket has at most 10 bits a side
  // (Record::cell, 30 bits).
  const int bucket_levels = std::max(std::min(grid.depth, kBucketLevels), grid.depth - 10);
  const int low_bits = 3 * (grid.depth - bucket_levels);
  const std::size_t buckets = std::size_t{1} << (3 * bucket_levels);
  const int threads = thread_count();
  Stores stores = file_triangles(mesh, grid, low_bits, buckets, threads);
  const std::vector<std::uint64_t> start = bucket_starts(stores, buckets);
  if (stats) {
    stats->record_bytes = 0;
    for (const auto& s : stores)
      stats->record_bytes += s->sums.records() * sizeof(Record) + s->singles.records() * sizeof(Single);
  }
  OctreeLeaves leaves(start[buckets]);
  const SharedSums sums = sum_buckets(stores, start, grid, low_bits, threads, leaves.block());
  stores.clear();
  if (stats) stats->buckets_taken_over = sums.buckets_taken_over;
  const Run window = join_runs(sums, leaves.block());
  leaves.set_window(window.begin, window.size);
  return leaves;
}

}  // namespace dentmark::detect::detail
