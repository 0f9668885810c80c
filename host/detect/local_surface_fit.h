#pragma once
// Each vertex's height over a robust local surface of its neighbours. On a coarse scan
// (4-6 mm between samples) a 9 mm defect covers one to three vertices and a map pixel of
// two spacings averages it away, so the test has to be made on the vertices themselves.
// Around each vertex a quadratic height field w(x, y) is fitted to the vertices in an
// annulus (the vertex's own near neighbours left out, so a defect of a few samples cannot
// lift its own reference), by iteratively reweighted least squares with Tukey's biweight
// (Huber, "Robust Statistics", §7.8; c = 4.685 robust σ, 95 % efficiency under Gaussian
// noise), which gives no weight to a handle's wall or a neighbouring defect in the
// annulus. The residual at the vertex, turned along the fitted surface's normal, is what a
// gauge held normal to the panel would read.

#include <Eigen/Core>
#include <vector>

namespace dentmark::detect {

struct LocalFitOptions {
  double inner_radius = 0.0;  // m: neighbours closer than this are left out
  double outer_radius = 0.0;  // m: and those farther
  int min_points = 12;        // fewer in the annulus: no fit (NaN)
  int iterations = 5;         // reweightings after the least-squares start
};

// points: (x, y, w) per vertex in a frame whose w is roughly the panel's normal (a height
// map's u, v, w); non-finite points are skipped. Returns, per point, its residual along
// the local surface's normal (m; positive towards +w; NaN where no fit).
std::vector<float> local_surface_residuals(const std::vector<Eigen::Vector3f>& points,
                                           const LocalFitOptions& options);

// The residual along the normal of point p = (0, 0, w0) over the robust quadratic fitted
// to 'ring' (coordinates relative to p, in m); NaN when under min_points remain or the
// fit is singular. One vertex's fit, exposed for tests.
double robust_quadratic_residual(double w0, const std::vector<Eigen::Vector3d>& ring,
                                 const LocalFitOptions& options);

}  // namespace dentmark::detect
