#pragma once
// The reference surface a defect is measured against: at each pixel of the height map,
// the weighted least-squares quadratic over a square window around it (moving least
// squares). Fits are made at tile centres from window sums of per-tile moments (an
// integral image over tiles) and blended bilinearly between the four nearest.
//
// Detection refits with the defect candidates left out, and only those tiles' weights
// change: a refit redoes only the tiles whose weights changed, the fits whose window
// holds one, and the pixels blended from those fits. Its result is the same as a fit
// from scratch: to the last bit as a rule, within float rounding (nanometres) where the
// integral image's changed prefix rounds a far tile's window sums differently.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <utility>
#include <vector>

#include "dentmark/host/detect/height_map.h"

namespace dentmark::detect {

class ReferenceSurface {
 public:
  // window: the side of the fitting window (m).
  ReferenceSurface(const HeightMap& map, double window);

  // Per pixel: the reference height w (map coordinates, m), NaN where no fit is possible.
  // weights: per pixel, 0 leaves the pixel out. Same size as the map.
  const std::vector<float>& fit(const std::vector<float>& weights);

  // The last fit's reference height at any point (u, v) of the map plane (m): the blend of
  // the four nearest tile fits, as at a pixel. NaN where no fit is near.
  double height_at(double u, double v) const;

  // Whether fits look for sharp folds (on by default). A chart of a panel that wraps round
  // (a tube of 0.15 m radius) turns too fast for the test that tells a fold from a curve:
  // the fits on either side of a tile disagree in slope there too.
  void look_for_folds(bool on) { look_for_folds_ = on; }

  // The last fit's heights per pixel (as fit() returned them).
  const std::vector<float>& heights() const { return ref_; }

  // Per pixel, non-zero on the last fit's fold lines: where no fit from either side
  // follows the pixels around (the fold's rounding). Empty where the map has no fold.
  const std::vector<std::uint8_t>& fold_lines() const { return fold_lines_; }

 private:
  // Moments of a tile or window: Σ ω x^a y^b (a + b <= 4) and Σ ω z x^a y^b (a + b <= 2)
  // in coordinates scaled to about [-1, 1].
  struct Moments {
    std::array<double, 25> m{};  // m[a * 5 + b]
    std::array<double, 9> h{};   // h[a * 3 + b]
    double zz = 0.0;             // Σ ω z², for the fit's residual
  };
  // The quadratic fitted at a tile centre, over local coordinates scaled by the window.
  struct Quadratic {
    bool ok = false;
    double cu = 0.0, cv = 0.0;                            // the centre (map coordinates, m)
    Eigen::Matrix<double, 6, 1> c = decltype(c)::Zero();  // 1, x, y, x², xy, y²
    double mean_square = 0.0;                             // the window's weighted residual
    double whole_mean_square = 0.0;                       // the same of the whole window's fit
    double weight = 0.0;                                  // the window's Σ ω
    bool wide = false;                                    // fitted over twice the window
    double at(double u, double v, double scale) const {
      const double x = (u - cu) * scale, y = (v - cv) * scale;
      return c(0) + c(1) * x + c(2) * y + c(3) * x * x + c(4) * x * y + c(5) * y * y;
    }
  };

  Moments tile_moments(int tx, int ty, const std::vector<float>& weights) const;
  void integrate();
  Quadratic fit_at(int tx, int ty) const;
  // The window sums of tiles within `radius` of (tx, ty).
  Moments window_at(int tx, int ty, int radius) const;
  // The map's own weight (before any is left out) in the same window.
  double capacity_at(int tx, int ty, int radius) const;
  // The quadratic (or plane) fitted to window sums about tile (tx, ty)'s centre, and its
  // weighted mean squared residual.
  Quadratic solve(const Moments& win, int tx, int ty, double& mean_square) const;
  void blend(int ty, int tx0, int tx1);  // the pixels of tiles [tx0, tx1) of tile row ty
  struct BlendCorner;
  std::vector<BlendCorner> blend_corners(int iy0, int ix0, int ny, int nx) const;
  // Beside a sharp fold (a character line) every window across it leaves a band as wide
  // as itself; there the pixels take the fits of windows beside them (fold_pass.cpp).
  static constexpr int kCandidates = 9;  // the eight side windows and the pixel's own blend
  struct FoldPixel {
    std::size_t k = 0;
    float share = 0.0f;
    float height[kCandidates];  // NaN: no clean candidate
    float weight[kCandidates];
    bool evidence = false;
    float fit_error = 0.0f;  // the best candidate's mean squared residual around (with evidence)
    float spread = 0.0f;     // the clean candidates' largest difference at the pixel
    bool crossing = false;   // the fits of two opposite side windows intersect here
  };
  void fold_pass();
  struct FoldScratch;
  void fold_block_grid(int bx, int by, FoldScratch& fs) const;
  bool fold_block_shares(int bx, int by, const std::vector<float>& share, FoldScratch& fs) const;
  void fold_candidates(int bx, int by, FoldScratch& fs) const;
  void fold_block_pixels(int bx, int by, FoldScratch& fs) const;
  struct SideFits;
  void side_fits(int dx, int dy, const FoldScratch& fs, SideFits& out) const;
  void fold_side_candidate(int d, FoldScratch& fs) const;
  void fold_own_candidate(int bx, int by, FoldScratch& fs) const;
  // Writes the block's pixels with a share to out (room for the block's); returns their count.
  int fold_evidence(int bx, int by, FoldScratch& fs, FoldPixel* out) const;
  bool crosses_fold(const FoldScratch& fs, std::size_t at, const bool* clean) const;
  // The slope (dw/du, dw/dv) of a tile's quadratic at a point of the map plane.
  std::array<double, 2> slope_at(const Quadratic& q, double u, double v) const;
  void fill_fold_weights(const std::vector<FoldPixel*>& pixels) const;
  void mark_fold_lines(const std::vector<FoldPixel*>& pixels);
  // How far the fold pass takes each tile from its own fit (0: not at all).
  std::vector<float> fold_shares() const;

  const HeightMap& map_;
  int tile_ = 4, radius_ = 1;  // tile side (pixels); window half-side (tiles)
  int tiles_x_ = 0, tiles_y_ = 0;
  double gu_ = 0.0, gv_ = 0.0, gs_ = 1.0;  // global centre and scale of coordinates
  double local_scale_ = 1.0;               // 1 / window half-side (1/m)
  std::vector<Moments> tiles_, integral_;
  std::vector<double> capacity_;  // integral image of the map's weights per tile
  std::vector<Quadratic> fits_;
  std::vector<float> weights_;  // of the last fit
  std::vector<float> ref_;
  // The blended heights of the pixels the last fold pass took, to restore first.
  std::vector<std::pair<std::size_t, float>> unfolded_;
  std::vector<std::uint8_t> fold_lines_;
  bool look_for_folds_ = true;
};

}  // namespace dentmark::detect
