#pragma once
// The reference surface a defect is measured against: at each pixel of the height map,
// the weighted least-squares quadratic over a square window around it (moving least
// squares). Fits are made at tile centres from window sums of per-tile moments (an
// integral image over tiles) and blended bilinearly between the four nearest.
//
// Detection refits with the defect candidates left out, and only those tiles' weights
// change: a refit redoes only the tiles whose weights changed, the fits whose window
// holds one, and the pixels blended from those fits. Its result is the same, to the
// last bit, as a fit from scratch.

#include <Eigen/Core>
#include <array>
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

  // The last fit's heights per pixel (as fit() returned them).
  const std::vector<float>& heights() const { return ref_; }

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
  };

  Moments tile_moments(int tx, int ty, const std::vector<float>& weights) const;
  void integrate();
  Quadratic fit_at(int tx, int ty) const;
  // The window sums of tiles within `radius` of (tx, ty).
  Moments window_at(int tx, int ty, int radius) const;
  // The quadratic (or plane) fitted to window sums about tile (tx, ty)'s centre, and its
  // weighted mean squared residual.
  Quadratic solve(const Moments& win, int tx, int ty, double& mean_square) const;
  void blend(int ty, int tx0, int tx1);  // the pixels of tiles [tx0, tx1) of tile row ty

  const HeightMap& map_;
  int tile_ = 4, radius_ = 1;  // tile side (pixels); window half-side (tiles)
  int tiles_x_ = 0, tiles_y_ = 0;
  double gu_ = 0.0, gv_ = 0.0, gs_ = 1.0;  // global centre and scale of coordinates
  double local_scale_ = 1.0;               // 1 / window half-side (1/m)
  std::vector<Moments> tiles_, integral_;
  std::vector<Quadratic> fits_;
  std::vector<float> weights_;  // of the last fit
  std::vector<float> ref_;
};

}  // namespace dentmark::detect
