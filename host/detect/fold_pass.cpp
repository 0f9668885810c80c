// The reference surface beside a sharp fold (a character line, 0.2 rad over a 2 mm
// radius). Every window across the fold fits one quadratic to both of its sides and
// leaves a band of deviation as wide as itself, where dents and bumps 15-30 mm from the
// line became part of the line (6 of 35 found: an independent generator's hoods).
//
// A generalised Kuwahara filter over the tile fits: where the windows on both sides of a
// tile fit better than its own and disagree in slope (fold_shares), each pixel within a
// window's half-side takes the fits of the windows shifted by the window's half-side in
// the eight directions, and its own blend, those that fit their own windows cleanly,
// weighted by how well they follow the pixels around it.
// A window that holds the pixel and fits cleanly lies on the pixel's side of the fold,
// and a fit from the other side is far off the pixels next to it (0.2 rad x 2 mm =
// 0.4 mm), so the band narrows to the fold's rounding. A defect cannot choose its own
// reference this way: the clean windows agree with each other within micrometres
// wherever only one side is in reach.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <new>
#include <type_traits>

#include "dentmark/common/nth_smallest.h"
#include "dentmark/host/detect/reference_surface.h"
#include "hot_loop.h"

namespace dentmark::detect {
namespace {

// A tile's window's mean square over the worse of two opposite windows beside it beyond
// which its window may hold a fold. Noise gives ratios within a few per cent of 1
// (windows of thousands of pixels); a window across a 0.2 rad fold, tens.
constexpr double kFoldRatio = 1.2;
// Mean squares below (2 µm)² are alike: a noise-free scan's are float rounding.
constexpr double kFloor = 4e-12;
// A side window is clean within this factor of the best one at the pixel.
constexpr double kClean = 2.0;
// The clean windows' fits are weighted by exp(-kSharpness (e / e_min - 1)), e the mean
// squared residual over the (2 kEvidence + 1)² pixels around.
constexpr double kSharpness = 3.0;
constexpr int kEvidence = 2;
// A side window this much emptier than the tile's own (the map's edge) does not count.
constexpr double kMinWeight = 0.9;

// The least difference in slope (rad) between the windows on either side of a fold.
constexpr double kMinJump = 0.04;
// The steepest tile fit (to the map plane) a fold is looked for at: 0.5, 27 degrees.
constexpr double kMaxSlope = 0.5;
// A pixel whose best candidate leaves this many times the typical mean square around it
// is on the fold's line (rms 3 x the noise; a pixel two from a 0.2 rad fold, 50 x).
constexpr double kLineError = 9.0;
// ... and where the candidates weighted over kLineWeight disagree by this many times the
// noise: on a defect every fit is far off, but those that follow the pixels around it
// come from its side of the fold and agree; across the fold's line those of both sides
// follow it equally badly.
constexpr double kLineSpread = 4.0;
constexpr float kLineWeight = 0.1f;
// ... or where the fits of an opposite pair of side windows intersect and their slopes
// along the pair differ by this much (half kMinJump: the pair may cross the fold at up
// to 60 degrees).
constexpr double kLineJump = 0.5 * kMinJump;
// The pixel's own blend, a candidate besides the eight side windows' fits.
constexpr int kOwn = 8;
// The pass works on blocks of whole tiles about this many pixels a side: each block's
// candidates are computed over it and a kEvidence margin, 1.27 times its pixels at 32
// (one 8-pixel tile a block: 2.25 times).
constexpr int kBlockPixels = 32;
// The largest block (pixels) plus its evidence margins the pass handles.
constexpr int kMaxSide = 64;
// The most rows (columns) of tile centres a block and its margins span (tiles are at
// least 4 pixels: reference_surface.cpp).
constexpr int kMaxSpan = kBlockPixels / 4 + 2;
// Pixels without evidence take it from pixels at most this many rings away.
constexpr int kFillRings = 24;

// FoldPixel blocks are malloc'ed, uninitialised (FoldPixel is trivially destructible).
struct FreeBlock {
  void operator()(void* p) const { std::free(p); }
};

constexpr int kDirections[8][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, 1}, {1, -1}, {-1, 1}, {-1, -1}};

}  // namespace

std::array<double, 2> ReferenceSurface::slope_at(const Quadratic& q, double u, double v) const {
  const double x = (u - q.cu) * local_scale_, y = (v - q.cv) * local_scale_;
  const auto& c = q.c;
  return {(c(1) + 2.0 * c(3) * x + c(4) * y) * local_scale_,
          (c(2) + c(4) * x + 2.0 * c(5) * y) * local_scale_};
}

std::vector<float> ReferenceSurface::fold_shares() const {
  std::vector<float> share(fits_.size(), 0.0f);
  std::vector<std::uint8_t> flagged(fits_.size(), 0);
  const int s = radius_;
  bool any = false;
#pragma omp parallel for schedule(static) reduction(|| : any)
  for (int ty = 0; ty < tiles_y_; ++ty)
    for (int tx = 0; tx < tiles_x_; ++tx) {
      const Quadratic& own = fits_[static_cast<std::size_t>(ty) * tiles_x_ + tx];
      // Not where the panel is steep to the map: there the window's own misfit changes
      // fast from tile to tile (a chart's ends, 30-55 degrees off its axis), and half and
      // quarter windows follow the panel (reference_surface.cpp).
      if (!own.ok || std::hypot(own.c(1), own.c(2)) * local_scale_ > kMaxSlope) continue;
      // A fold: the windows on both sides of the tile fit better than its own, and
      // their slopes, carried to its centre, differ by the fold's angle. A panel that
      // curves faster and faster one way (a fender's side, a chart's ends) also has
      // windows that fit better than the one across (partial ones at its edge), but
      // their slopes agree within 0.02 (measured at 0.25 m radius, +-55 degrees); a
      // 0.1 rad fold's differ by 0.05-0.1, a 0.2 rad one's by more.
      bool fold = false;
      for (int d = 0; d < 8 && !fold; d += 2) {
        const int ax = tx + s * kDirections[d][0], ay = ty + s * kDirections[d][1];
        const int bx = tx + s * kDirections[d + 1][0], by = ty + s * kDirections[d + 1][1];
        if (ax < 0 || ay < 0 || ax >= tiles_x_ || ay >= tiles_y_ || bx < 0 || by < 0 || bx >= tiles_x_ ||
            by >= tiles_y_)
          continue;
        const Quadratic& A = fits_[static_cast<std::size_t>(ay) * tiles_x_ + ax];
        const Quadratic& B = fits_[static_cast<std::size_t>(by) * tiles_x_ + bx];
        if (!A.ok || !B.ok || A.weight < kMinWeight * own.weight || B.weight < kMinWeight * own.weight)
          continue;
        if (!(own.whole_mean_square + kFloor >
              kFoldRatio * (std::max(A.whole_mean_square, B.whole_mean_square) + kFloor)))
          continue;
        const std::array<double, 2> ga = slope_at(A, own.cu, own.cv), gb = slope_at(B, own.cu, own.cv);
        fold = std::hypot(ga[0] - gb[0], ga[1] - gb[1]) > kMinJump;
      }
      flagged[static_cast<std::size_t>(ty) * tiles_x_ + tx] = fold;
      any = any || fold;
    }
  if (!any) return share;
  // The band reaches as far as the windows across the fold: the window's half-side.
  for (int ty = 0; ty < tiles_y_; ++ty)
    for (int tx = 0; tx < tiles_x_; ++tx)
      if (flagged[static_cast<std::size_t>(ty) * tiles_x_ + tx])
        for (int y = std::max(0, ty - s); y <= std::min(tiles_y_ - 1, ty + s); ++y)
          for (int x = std::max(0, tx - s); x <= std::min(tiles_x_ - 1, tx + s); ++x)
            share[static_cast<std::size_t>(y) * tiles_x_ + x] = 1.0f;
  return share;
}

// One thread's working arrays for a block and the kEvidence pixels around it (side x side),
// candidate d's at [d][y][x].
struct ReferenceSurface::FoldScratch {
  explicit FoldScratch(int block_side)
      : block(block_side),
        side(block + 2 * kEvidence),
        f(static_cast<std::size_t>(kCandidates * side * side)),
        ms(f.size()),
        have(f.size()),
        resid(f.size()),
        weight(f.size()),
        z(static_cast<std::size_t>(side * side)),
        w(z.size()),
        weighed(z.size()),
        mono(6 * z.size()),
        shares(static_cast<std::size_t>(block * block)),
        across(static_cast<std::size_t>(2 * side * block)),
        sums(static_cast<std::size_t>(2 * kCandidates * block * block)) {}
  int block;  // the block's side (pixels)
  int side;   // ... with its margins
  // Per row and column of the square: the lower of its pixels' two nearest rows and
  // columns of tile centres, and its fraction of the way to the next (as in blend()).
  int row_tile[kMaxSide], col_tile[kMaxSide];
  double row_frac[kMaxSide], col_frac[kMaxSide];
  float col_frac_f[kMaxSide];
  // The block's centre on the map plane (m), the rows and columns of tile centres it
  // spans, and the runs of columns that share their four nearest tiles
  // ([run_start[g], run_start[g + 1])).
  double uc = 0.0, vc = 0.0;
  int spans_y = 0, spans_x = 0;
  int run_start[kMaxSpan + 1];
  // Per pixel in floats (twice as many per vector as doubles): heights within centimetres
  // of the map plane round to nanometres, as in blend(); their squared residuals, sums of
  // 25, to a few parts in 10^7.
  std::vector<float> f, ms;  // the candidate's height and its windows' mean square
  std::vector<std::uint8_t> have;
  std::vector<float> resid, weight;   // its weighted squared residual and weight (0: none)
  std::vector<float> z, w;            // the map's heights and weights (0 off the map)
  std::vector<std::uint8_t> weighed;  // w > 0
  std::vector<float> mono;            // [i][y][x]: 1, X, Y, X², XY, Y² about the block's centre
  std::vector<double> shares;
  std::vector<float> across;  // the evidence's sums along rows: [residual or weight][y][x]
  std::vector<float> sums;    // ... and over the square: [d][residual or weight][y][x]
};

void ReferenceSurface::fold_pass() {
  unfolded_.clear();
  fold_lines_.clear();
  if (!look_for_folds_) return;
  const std::vector<float> share = fold_shares();
  std::vector<std::uint8_t> folded(share.size(), 0);
  bool any = false;
  for (std::size_t t = 0; t < share.size(); ++t) folded[t] = share[t] > 0.0f, any = any || folded[t];
  if (!any) return;
  // Blocks of B x B tiles. A pixel blends the shares of its four nearest tiles, so the
  // pass takes the blocks that hold a tile next to a folded one (their other tiles'
  // pixels have no share). (Tiles are window / 8: a 64 mm window of 1 mm pixels is 8.)
  const int B = std::max(1, kBlockPixels / tile_), P = B * tile_;
  if (P + 2 * kEvidence > kMaxSide) return;
  const int blocks_x = (tiles_x_ + B - 1) / B, blocks_y = (tiles_y_ + B - 1) / B;
  std::vector<std::uint8_t> in_block(static_cast<std::size_t>(blocks_x) * blocks_y, 0);
  for (int ty = 0; ty < tiles_y_; ++ty)
    for (int tx = 0; tx < tiles_x_; ++tx) {
      bool near = false;
      for (int y = std::max(0, ty - 1); y <= std::min(tiles_y_ - 1, ty + 1); ++y)
        for (int x = std::max(0, tx - 1); x <= std::min(tiles_x_ - 1, tx + 1); ++x)
          near = near || folded[static_cast<std::size_t>(y) * tiles_x_ + x];
      if (near) in_block[static_cast<std::size_t>(ty / B) * blocks_x + tx / B] = 1;
    }
  std::vector<int> blocks;
  for (std::size_t b = 0; b < in_block.size(); ++b)
    if (in_block[b]) blocks.push_back(static_cast<int>(b));
  // Per pixel of those blocks: its share and its candidates (the eight side windows' fits
  // and its own blend), with their weights where the pixels around gave evidence.
  // (P² a block, each block's pixels first: no allocation in the threads. Not
  // initialised: each block's thread writes its pixels; zeroing the whole, tens of MB
  // along a door's crease, kept the other thread waiting.)
  const std::size_t per_block = static_cast<std::size_t>(P) * P;
  static_assert(std::is_trivially_destructible_v<FoldPixel>);
  const std::unique_ptr<FoldPixel[], FreeBlock> found(
      static_cast<FoldPixel*>(std::malloc(blocks.size() * per_block * sizeof(FoldPixel))));
  if (!found) throw std::bad_alloc();
  std::vector<int> found_count(blocks.size(), 0);
#pragma omp parallel
  {
    FoldScratch scratch(P);
#pragma omp for schedule(dynamic, 1)
    for (std::size_t i = 0; i < blocks.size(); ++i) {
      const int bx = blocks[i] % blocks_x, by = blocks[i] / blocks_x;
      fold_block_grid(bx, by, scratch);
      if (!fold_block_shares(bx, by, share, scratch)) continue;
      fold_candidates(bx, by, scratch);
      found_count[i] = fold_evidence(bx, by, scratch, found.get() + i * per_block);
    }
  }
  std::vector<FoldPixel*> pixels;  // (pointers: the lists are large)
  for (std::size_t i = 0; i < blocks.size(); ++i)
    for (int j = 0; j < found_count[i]; ++j)
      pixels.push_back(&found[i * per_block + static_cast<std::size_t>(j)]);
  mark_fold_lines(pixels);
  fill_fold_weights(pixels);
  // (Every pixel's blend is kept to restore, changed or not: each is a pixel of its own.)
  unfolded_.resize(pixels.size());
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    const FoldPixel& px = *pixels[i];
    unfolded_[i] = {px.k, ref_[px.k]};
    double h = 0.0, ws = 0.0;
    for (int d = 0; d < kCandidates; ++d)
      if (px.weight[d] > 0.0f && std::isfinite(px.height[d]))
        h += px.weight[d] * px.height[d], ws += px.weight[d];
    if (ws > 0.0) ref_[px.k] = static_cast<float>((1.0 - px.share) * ref_[px.k] + px.share * h / ws);
  }
}

// The scratch's rows and columns of tile centres for the block and its margin, as blend()
// finds a pixel's four nearest fits.
void ReferenceSurface::fold_block_grid(int bx, int by, FoldScratch& fs) const {
  const int T = tile_, e = kEvidence;
  const int r0 = by * fs.block - e, c0 = bx * fs.block - e;
  for (int x = 0; x < fs.side; ++x) {
    const double fx = (c0 + x + 0.5) / T - 0.5;
    fs.col_tile[x] = static_cast<int>(std::floor(fx)), fs.col_frac[x] = fx - fs.col_tile[x];
    fs.col_frac_f[x] = static_cast<float>(fs.col_frac[x]);
    const double fy = (r0 + x + 0.5) / T - 0.5;
    fs.row_tile[x] = static_cast<int>(std::floor(fy)), fs.row_frac[x] = fy - fs.row_tile[x];
  }
}

// The block's pixels' shares: the bilinear blend of their four nearest tiles'. False if
// none has a share.
bool ReferenceSurface::fold_block_shares(int bx, int by, const std::vector<float>& share,
                                         FoldScratch& fs) const {
  const int P = fs.block, e = kEvidence;
  bool any = false;
  for (int y = 0; y < P; ++y)
    for (int x = 0; x < P; ++x) {
      const int r = by * P + y, c = bx * P + x;
      double a = 0.0;
      if (r < map_.rows && c < map_.cols) {
        const int iy = fs.row_tile[y + e], ix = fs.col_tile[x + e];
        const double ay = fs.row_frac[y + e], ax = fs.col_frac[x + e];
        for (int n = 0; n < 4; ++n)
          a += (n / 2 ? ay : 1.0 - ay) * (n % 2 ? ax : 1.0 - ax) *
               share[static_cast<std::size_t>(std::clamp(iy + n / 2, 0, tiles_y_ - 1)) * tiles_x_ +
                     std::clamp(ix + n % 2, 0, tiles_x_ - 1)];
      }
      fs.shares[static_cast<std::size_t>(y * P + x)] = a;
      any = any || a > 0.0;
    }
  return any;
}

namespace {

// Over a run of pixels that share their four nearest tiles: the blend (A + ax B) /
// (wa + ax wb) of the quadratics A and B at the pixels (monomials X ... YY), and the same
// of the fits' mean squares. Separate so that it vectorises.
[[gnu::always_inline]] inline void blend_run(int n, const float* __restrict X, const float* __restrict Y,
                                             const float* __restrict XX, const float* __restrict XY,
                                             const float* __restrict YY, const float* __restrict ax,
                                             const float* __restrict A, const float* __restrict B, float mA,
                                             float mB, float wa, float wb, float* __restrict f,
                                             float* __restrict ms) {
  for (int x = 0; x < n; ++x) {
    const float a = A[0] + A[1] * X[x] + A[2] * Y[x] + A[3] * XX[x] + A[4] * XY[x] + A[5] * YY[x];
    const float b = B[0] + B[1] * X[x] + B[2] * Y[x] + B[3] * XX[x] + B[4] * XY[x] + B[5] * YY[x];
    const float inv = 1.0f / (wa + ax[x] * wb);
    f[x] = (a + ax[x] * b) * inv, ms[x] = (mA + ax[x] * mB) * inv;
  }
}

// A += alpha c, B += beta c, over eight, four at a time (GCC left the loop scalar).
[[gnu::always_inline]] inline void add_scaled(double* __restrict A, double* __restrict B,
                                              const double* __restrict c, double alpha, double beta) {
  using Four = double __attribute__((vector_size(32)));
  for (int h = 0; h < 8; h += 4) {
    Four a, b, of_c;
    std::memcpy(&a, A + h, sizeof a), std::memcpy(&b, B + h, sizeof b),
        std::memcpy(&of_c, c + h, sizeof of_c);
    a += alpha * of_c, b += beta * of_c;
    std::memcpy(A + h, &a, sizeof a), std::memcpy(B + h, &b, sizeof b);
  }
}

// Each candidate's weighted squared residual and weight per pixel (0 without it).
[[gnu::always_inline]] inline void evidence_terms(std::size_t n, const float* __restrict z,
                                                  const float* __restrict w, const float* __restrict f,
                                                  const std::uint8_t* __restrict have,
                                                  float* __restrict resid, float* __restrict weight) {
  for (std::size_t p = 0; p < n; ++p) {
    const float dz = z[p] - f[p];
    resid[p] = have[p] ? w[p] * dz * dz : 0.0f;
    weight[p] = have[p] ? w[p] : 0.0f;
  }
}

// Rows y .. y + 2 kEvidence of the row sums (T apart, from ar and aw) added down
// columns, in order, to sr and sw.
[[gnu::always_inline]] inline void sum_down(int T, const float* __restrict ar, const float* __restrict aw,
                                            float* __restrict sr, float* __restrict sw) {
  for (int x = 0; x < T; ++x) sr[x] = 0.0f, sw[x] = 0.0f;
  for (int i = 0; i <= 2 * kEvidence; ++i)
    for (int x = 0; x < T; ++x) sr[x] += ar[i * T + x], sw[x] += aw[i * T + x];
}

}  // namespace

// Every candidate over the block and its margin: the bilinear blend of the fits of the
// tiles (dx, dy) from each pixel's four nearest, as blend() and height_at() do, and the
// pixel's own blend. Also each candidate's weighted squared residual and weight per
// pixel, for the evidence. (After fold_block_grid.)
void ReferenceSurface::fold_candidates(int bx, int by, FoldScratch& fs) const {
  fold_block_pixels(bx, by, fs);
  if (fs.spans_y > kMaxSpan || fs.spans_x > kMaxSpan) return;
  for (int d = 0; d < kOwn; ++d) fold_side_candidate(d, fs);
  fold_own_candidate(bx, by, fs);
  // What the evidence sums.
  const std::size_t area = static_cast<std::size_t>(fs.side * fs.side);
  for (int d = 0; d < kCandidates; ++d)
    evidence_terms(area, fs.z.data(), fs.w.data(), fs.f.data() + d * area, fs.have.data() + d * area,
                   fs.resid.data() + d * area, fs.weight.data() + d * area);
}

// The block's pixels and its margin's: the map's height and weight (0 off the map), the
// monomials 1, X, Y, X², XY, Y² of their position about the block's centre; and the
// rows and columns of tile centres they span, with the runs of columns that share
// their four nearest tiles.
DENTMARK_HOT_LOOP void ReferenceSurface::fold_block_pixels(int bx, int by, FoldScratch& fs) const {
  const int P = fs.block, e = kEvidence, side = fs.side;
  const std::size_t area = static_cast<std::size_t>(side * side);
  const int r0 = by * P - e, c0 = bx * P - e;
  // A pixel's four nearest fits are at tiles (iy + n / 2, ix + n % 2), iy and ix its
  // lower row and column of tile centres: over the block and its margin, one of kMaxSpan
  // (a block of B tiles a side spans at most B + 2).
  fs.spans_y = fs.row_tile[side - 1] - fs.row_tile[0] + 1;
  fs.spans_x = fs.col_tile[side - 1] - fs.col_tile[0] + 1;
  fs.uc = map_.u0 + (bx * P + 0.5 * P) * map_.pixel;
  fs.vc = map_.v0 + (by * P + 0.5 * P) * map_.pixel;
  for (int y = 0; y < side; ++y)
    for (int x = 0; x < side; ++x) {
      const std::size_t p = static_cast<std::size_t>(y * side + x);
      const int r = r0 + y, c = c0 + x;
      const bool on_map = r >= 0 && c >= 0 && r < map_.rows && c < map_.cols;
      const std::size_t k = on_map ? static_cast<std::size_t>(r) * map_.cols + c : 0;
      const bool weighed = on_map && map_.weight[k] > 0.0f;
      fs.weighed[p] = weighed;
      fs.w[p] = weighed ? map_.weight[k] : 0.0f;
      fs.z[p] = weighed ? map_.w[k] : 0.0f;
      const double X = weighed ? (map_.u[k] - fs.uc) * local_scale_ : 0.0,
                   Y = weighed ? (map_.v[k] - fs.vc) * local_scale_ : 0.0;
      const double mono[6] = {1.0, X, Y, X * X, X * Y, Y * Y};
      for (int i = 0; i < 6; ++i) fs.mono[i * area + p] = static_cast<float>(mono[i]);
    }
  if (fs.spans_y > kMaxSpan || fs.spans_x > kMaxSpan) return;
  // The runs of columns that share their four nearest tiles: [run_start[g], run_start[g + 1]).
  for (int g = 0, x = 0; g <= fs.spans_x; ++g) {
    while (x < side && fs.col_tile[x] - fs.col_tile[0] < g) ++x;
    fs.run_start[g] = x;
  }
}

// The fit of the window (dx, dy) tiles from each tile the block's pixels blend,
// re-expanded about the block's centre, or none: beyond the map, or a window beside the
// map's or the panel's edge, mostly empty, that fits its few pixels closely and
// extrapolates wildly. Per tile: the six coefficients, the window's mean square and 1
// (for the blend's weights), eight so that the blend vectorises.
struct ReferenceSurface::SideFits {
  alignas(32) double coef[kMaxSpan + 1][kMaxSpan + 1][8];
  bool valid[kMaxSpan + 1][kMaxSpan + 1] = {};
};

void ReferenceSurface::side_fits(int dx, int dy, const FoldScratch& fs, SideFits& out) const {
  for (int gy = 0; gy <= fs.spans_y; ++gy)
    for (int gx = 0; gx <= fs.spans_x; ++gx) {
      const int ty = std::clamp(fs.row_tile[0] + gy, 0, tiles_y_ - 1),
                tx = std::clamp(fs.col_tile[0] + gx, 0, tiles_x_ - 1);
      const int ny = ty + dy, nx = tx + dx;
      if (nx < 0 || ny < 0 || nx >= tiles_x_ || ny >= tiles_y_) continue;
      const Quadratic& q = fits_[static_cast<std::size_t>(ny) * tiles_x_ + nx];
      out.valid[gy][gx] =
          q.ok && q.weight >= kMinWeight * fits_[static_cast<std::size_t>(ty) * tiles_x_ + tx].weight;
      if (!out.valid[gy][gx]) continue;
      // Its quadratic in x = X + a, y = Y + b, expanded in X, Y.
      const double a = (fs.uc - q.cu) * local_scale_, b = (fs.vc - q.cv) * local_scale_;
      const auto& c = q.c;
      const double about[6] = {c(0) + c(1) * a + c(2) * b + c(3) * a * a + c(4) * a * b + c(5) * b * b,
                               c(1) + 2.0 * c(3) * a + c(4) * b,
                               c(2) + c(4) * a + 2.0 * c(5) * b,
                               c(3),
                               c(4),
                               c(5)};
      std::copy(about, about + 6, out.coef[gy][gx]);
      out.coef[gy][gx][6] = q.mean_square, out.coef[gy][gx][7] = 1.0;
    }
}

// Side candidate d over the block and its margin: each pixel's bilinear blend of the
// side fits of its four nearest tiles, and of their windows' mean squares.
DENTMARK_HOT_LOOP void ReferenceSurface::fold_side_candidate(int d, FoldScratch& fs) const {
  const int side = fs.side, s = radius_;
  const std::size_t area = static_cast<std::size_t>(side * side);
  SideFits fits;
  side_fits(s * kDirections[d][0], s * kDirections[d][1], fs, fits);
  bool cell_ok[kMaxSpan][kMaxSpan];
  for (int gy = 0; gy < fs.spans_y; ++gy)
    for (int gx = 0; gx < fs.spans_x; ++gx)
      cell_ok[gy][gx] = fits.valid[gy][gx] && fits.valid[gy][gx + 1] && fits.valid[gy + 1][gx] &&
                        fits.valid[gy + 1][gx + 1];
  const float *X = fs.mono.data() + area, *Y = X + area, *XX = Y + area, *XY = XX + area, *YY = XY + area;
  float* f = fs.f.data() + d * area;
  float* ms = fs.ms.data() + d * area;
  std::uint8_t* have = fs.have.data() + d * area;
  for (int y = 0; y < side; ++y) {
    const int gy = fs.row_tile[y] - fs.row_tile[0];
    for (int gx = 0; gx < fs.spans_x; ++gx) {
      const int x0 = fs.run_start[gx], x1 = fs.run_start[gx + 1];
      const std::size_t p0 = static_cast<std::size_t>(y * side + x0);
      if (!cell_ok[gy][gx]) {
        std::fill(have + p0, have + p0 + (x1 - x0), 0);
        continue;
      }
      std::copy(fs.weighed.data() + p0, fs.weighed.data() + p0 + (x1 - x0), have + p0);
      // Along the run only the column fraction ax changes: fit n weighs
      // (1 - ax or ax) * (1 - ay or ay) + 1e-9 = alpha + ax beta, and the blend is
      // (A + ax B) / (wa + ax wb), as in blend().
      // (A[6], B[6]: the same of the mean squares; A[7], B[7]: wa, wb.)
      alignas(32) double A[8] = {}, B[8] = {};
      for (int n = 0; n < 4; ++n) {
        const double wy = n / 2 ? fs.row_frac[y] : 1.0 - fs.row_frac[y];
        const double alpha = n % 2 ? 1e-9 : wy + 1e-9, beta = n % 2 ? wy : -wy;
        add_scaled(A, B, fits.coef[gy + n / 2][gx + n % 2], alpha, beta);
      }
      alignas(32) float Af[8], Bf[8];
      for (int i = 0; i < 8; ++i) Af[i] = static_cast<float>(A[i]), Bf[i] = static_cast<float>(B[i]);
      blend_run(x1 - x0, X + p0, Y + p0, XX + p0, XY + p0, YY + p0, fs.col_frac_f + x0, Af, Bf, Af[6], Bf[6],
                Af[7], Bf[7], f + p0, ms + p0);
    }
  }
}

// The pixel's own candidate: its blend as blend() made it, and its four fits' windows'
// mean square blended alike (the block's pixels').
DENTMARK_HOT_LOOP void ReferenceSurface::fold_own_candidate(int bx, int by, FoldScratch& fs) const {
  const int P = fs.block, e = kEvidence, side = fs.side;
  const std::size_t area = static_cast<std::size_t>(side * side);
  const int r0 = by * P - e, c0 = bx * P - e;
  float* f = fs.f.data() + kOwn * area;
  float* own_ms = fs.ms.data() + kOwn * area;
  std::uint8_t* have = fs.have.data() + kOwn * area;
  for (int y = 0; y < side; ++y)
    for (int x = 0; x < side; ++x) {
      const std::size_t p = static_cast<std::size_t>(y * side + x);
      have[p] = 0;
      if (!fs.weighed[p]) continue;
      const int r = r0 + y, c = c0 + x;
      f[p] = ref_[static_cast<std::size_t>(r) * map_.cols + c];
      have[p] = std::isfinite(f[p]);
      if (!have[p] || y < e || y >= e + P || x < e || x >= e + P) continue;
      const int iy = fs.row_tile[y], ix = fs.col_tile[x];
      const double ay = fs.row_frac[y], ax = fs.col_frac[x];
      double sum = 0.0, ws = 0.0;
      for (int n = 0; n < 4 && have[p]; ++n) {
        const Quadratic& q =
            fits_[static_cast<std::size_t>(std::clamp(iy + n / 2, 0, tiles_y_ - 1)) * tiles_x_ +
                  std::clamp(ix + n % 2, 0, tiles_x_ - 1)];
        have[p] = q.ok;
        const double wn = (n / 2 ? ay : 1.0 - ay) * (n % 2 ? ax : 1.0 - ax) + 1e-9;
        sum += wn * q.mean_square, ws += wn;
      }
      if (have[p]) own_ms[p] = static_cast<float>(sum / ws);
    }
}

// Per pixel of the block with a share: its clean candidates, weighted by how well they
// follow the (2 kEvidence + 1)² pixels around it.
DENTMARK_HOT_LOOP int ReferenceSurface::fold_evidence(int bx, int by, FoldScratch& fs, FoldPixel* out) const {
  int count = 0;
  const int P = fs.block, e = kEvidence, side = fs.side;
  const std::size_t square = static_cast<std::size_t>(P * P);

  // Each candidate's weighted squared residuals and weights summed over the square
  // around each pixel: along rows, then down columns.
  for (int d = 0; d < kCandidates; ++d) {
    const std::size_t base = static_cast<std::size_t>(d * side * side);
    float* across_resid = fs.across.data();
    float* across_weight = fs.across.data() + static_cast<std::size_t>(side * P);
    for (int y = 0; y < side; ++y)
      for (int x = 0; x < P; ++x) {
        float sr = 0.0f, sw = 0.0f;
        for (int i = 0; i <= 2 * e; ++i) {
          const std::size_t j = base + static_cast<std::size_t>(y * side + x + i);
          sr += fs.resid[j], sw += fs.weight[j];
        }
        across_resid[y * P + x] = sr, across_weight[y * P + x] = sw;
      }
    float* sum_resid = fs.sums.data() + 2 * d * square;
    float* sum_weight = sum_resid + square;
    for (int y = 0; y < P; ++y)
      sum_down(P, across_resid + y * P, across_weight + y * P, sum_resid + y * P, sum_weight + y * P);
  }
  for (int y = 0; y < P; ++y)
    for (int x = 0; x < P; ++x) {
      const int r = by * P + y, c = bx * P + x;
      if (r >= map_.rows || c >= map_.cols) continue;
      const std::size_t k = static_cast<std::size_t>(r) * map_.cols + c;
      if (!(map_.weight[k] > 0.0f) || !std::isfinite(ref_[k])) continue;
      const double a = fs.shares[static_cast<std::size_t>(y * P + x)];
      if (!(a > 0.0)) continue;
      const std::size_t at = static_cast<std::size_t>((y + e) * side + x + e),
                        own = static_cast<std::size_t>(y * P + x);
      FoldPixel px;
      px.k = k, px.share = static_cast<float>(a);
      double best_ms = std::numeric_limits<double>::infinity();
      for (int d = 0; d < kCandidates; ++d) {
        const std::size_t j = static_cast<std::size_t>(d * side * side) + at;
        px.height[d] = fs.have[j] ? static_cast<float>(fs.f[j]) : std::numeric_limits<float>::quiet_NaN();
        if (fs.have[j]) best_ms = std::min<double>(best_ms, fs.ms[j]);
      }
      // Evidence: the clean windows' residuals over the pixels around (the pixel's own
      // blend among them where its window is clean too).
      double resid[kCandidates];
      double best_resid = std::numeric_limits<double>::infinity();
      for (int d = 0; d < kCandidates; ++d) {
        resid[d] = std::numeric_limits<double>::infinity();
        const std::size_t j = static_cast<std::size_t>(d * side * side) + at;
        if (!fs.have[j] || fs.ms[j] + kFloor > kClean * (best_ms + kFloor)) {
          px.height[d] = std::numeric_limits<float>::quiet_NaN();  // not clean: no candidate
          continue;
        }
        const double sum = fs.sums[2 * d * square + own], wsum = fs.sums[(2 * d + 1) * square + own];
        if (wsum > 0.0) resid[d] = sum / wsum, best_resid = std::min(best_resid, resid[d]);
      }
      px.evidence = std::isfinite(best_resid);
      if (px.evidence) px.fit_error = static_cast<float>(best_resid);
      // (The exponential in floats, the weights' own precision: half the cost.)
      for (int d = 0; d < kCandidates; ++d)
        px.weight[d] =
            px.evidence && std::isfinite(resid[d])
                ? std::exp(static_cast<float>(-kSharpness * (resid[d] - best_resid) / (best_resid + kFloor)))
                : 0.0f;
      // How far the candidates that follow the pixels around about as well as the best
      // differ: apart only where fits from both sides do (the fold's line).
      float lo = std::numeric_limits<float>::infinity(), hi = -lo;
      for (int d = 0; d < kCandidates; ++d)
        if (px.weight[d] > kLineWeight && std::isfinite(px.height[d]))
          lo = std::min(lo, px.height[d]), hi = std::max(hi, px.height[d]);
      px.spread = hi > lo ? hi - lo : 0.0f;
      bool clean[kCandidates];
      for (int d = 0; d < kCandidates; ++d) clean[d] = std::isfinite(px.height[d]);
      px.crossing = crosses_fold(fs, at, clean);
      new (out + count++) FoldPixel(px);  // (out is raw memory)
    }
  return count;
}

// Whether the fold's line passes between the pixel at 'at' (in the scratch) and the next
// one along an opposite pair of side windows' direction, both clean there: there the two
// windows' fits, each the surface of one side carried across the fold, intersect.
// (Further from the line, one of them holds the fold too: a quadratic over a V overshoots
// at its ends, and meets the other side's fit again, but does not fit cleanly.) Their difference
// changes sign there and grows with the fold's angle on either side; for a pair along
// the fold it stays near zero. The fits span whole windows, so the line is found
// whatever the noise, where the pixels' residuals only show it in pieces.
bool ReferenceSurface::crosses_fold(const FoldScratch& fs, std::size_t at, const bool* clean) const {
  const int side = fs.side;
  const std::size_t area = static_cast<std::size_t>(side * side);
  for (int d = 0; d < kOwn; d += 2) {
    if (!clean[d] || !clean[d + 1]) continue;
    const std::ptrdiff_t step = kDirections[d][1] * side + kDirections[d][0];
    const double length = std::hypot(kDirections[d][0], kDirections[d][1]) * map_.pixel;
    double diff[4];  // at -2, 0, +1, +2 steps
    bool ok = true;
    constexpr int kAt[4] = {-2, 0, 1, 2};
    for (int i = 0; i < 4 && ok; ++i) {
      const std::size_t j = static_cast<std::size_t>(static_cast<std::ptrdiff_t>(at) + kAt[i] * step);
      ok = fs.have[d * area + j] && fs.have[(d + 1) * area + j];
      if (ok) diff[i] = fs.f[d * area + j] - fs.f[(d + 1) * area + j];
    }
    if (ok && (diff[1] > 0.0) != (diff[2] > 0.0) && std::abs(diff[3] - diff[0]) > kLineJump * 4.0 * length)
      return true;
  }
  return false;
}

// The fold's own line: pixels whose best candidate leaves far more around them than
// the fold region's typical pixel (its noise), there being no side to take.
void ReferenceSurface::mark_fold_lines(const std::vector<FoldPixel*>& pixels) {
  // (Gathered side by side, in any order: the median is one value.)
  std::vector<float> errors;
#pragma omp parallel
  {
    std::vector<float> mine;
#pragma omp for schedule(static) nowait
    for (std::size_t i = 0; i < pixels.size(); ++i)
      if (pixels[i]->evidence) mine.push_back(pixels[i]->fit_error);
#pragma omp critical
    errors.insert(errors.end(), mine.begin(), mine.end());
  }
  if (errors.empty()) return;
  const double typical = nth_smallest(errors, errors.size() / 2);
  fold_lines_.assign(map_.size(), 0);
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    const FoldPixel* px = pixels[i];
    if (px->crossing || (px->evidence && px->fit_error > kLineError * typical + kFloor &&
                         px->spread > kLineSpread * std::sqrt(typical + kFloor)))
      fold_lines_[px->k] = 255;
  }
}

// Pixels without evidence (a defect and the margin around it, left out of the fit; the
// fold's own line, once found) take the weights of the nearest pixels with evidence,
// ring by ring: the side of the fold they lie on.
void ReferenceSurface::fill_fold_weights(const std::vector<FoldPixel*>& pixels) const {
  std::vector<std::size_t> waiting;
  for (std::size_t i = 0; i < pixels.size(); ++i)
    if (!pixels[i]->evidence) waiting.push_back(i);
  if (waiting.empty()) return;
  std::vector<std::int32_t> slot(map_.size(), -1);
  for (std::size_t i = 0; i < pixels.size(); ++i) slot[pixels[i]->k] = static_cast<std::int32_t>(i);
  for (int ring = 0; ring < kFillRings && !waiting.empty(); ++ring) {
    std::vector<std::pair<std::size_t, std::array<float, kCandidates>>> filled;
    std::vector<std::size_t> still;
    for (const std::size_t i : waiting) {
      const int r = static_cast<int>(pixels[i]->k / map_.cols),
                c = static_cast<int>(pixels[i]->k % map_.cols);
      std::array<float, kCandidates> sum{};
      int n = 0;
      for (int dr = -1; dr <= 1; ++dr)
        for (int dc = -1; dc <= 1; ++dc) {
          const int rr = r + dr, cc = c + dc;
          if (rr < 0 || cc < 0 || rr >= map_.rows || cc >= map_.cols) continue;
          const std::int32_t j = slot[static_cast<std::size_t>(rr) * map_.cols + cc];
          if (j < 0 || !pixels[static_cast<std::size_t>(j)]->evidence) continue;
          for (int d = 0; d < kCandidates; ++d) sum[d] += pixels[static_cast<std::size_t>(j)]->weight[d];
          ++n;
        }
      if (n > 0)
        filled.emplace_back(i, sum);
      else
        still.push_back(i);
    }
    // Taken over after the ring: the result does not depend on the order within it.
    for (const auto& [i, sum] : filled) {
      std::copy(sum.begin(), sum.end(), pixels[i]->weight);
      pixels[i]->evidence = true;
    }
    waiting.swap(still);
  }
}

}  // namespace dentmark::detect
