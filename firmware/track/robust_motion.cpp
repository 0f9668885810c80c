#include "dentmark/firmware/track/robust_motion.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

#include "dentmark/common/geometry/rigid_fit.h"
#include "dentmark/common/nth_smallest.h"

namespace dentmark::track {
namespace {

std::vector<double> residuals(const Transform& t, std::span<const Eigen::Vector3d> from,
                              std::span<const Eigen::Vector3d> to) {
  std::vector<double> r(from.size());
  for (std::size_t i = 0; i < from.size(); ++i) r[i] = (to[i] - t * from[i]).norm();
  return r;
}

}  // namespace

RobustMotion fit_rigid_robust(std::span<const Eigen::Vector3d> from, std::span<const Eigen::Vector3d> to,
                              std::span<const double> prior, const RobustMotionOptions& o) {
  const std::size_t n = from.size();
  if (n < 3 || to.size() != n || (!prior.empty() && prior.size() != n))
    throw GeometryError("fit_rigid_robust: need at least 3 corresponding points");
  std::vector<double> w0(n, 1.0);
  if (!prior.empty()) w0.assign(prior.begin(), prior.end());

  RobustMotion out;
  RigidFit all = fit_rigid(from, to, w0);
  std::vector<double> r = residuals(all.T_to_from, from, to);
  double scale = o.noise_floor;
  Transform t = all.T_to_from;
  if (*std::max_element(r.begin(), r.end()) > o.outlier_sigmas * o.noise_floor) {
    // Least median of squares over minimal samples (all triplets for a handful of
    // features): up to half the features may be wrong without pulling the start.
    double best = std::numeric_limits<double>::infinity();
    std::vector<Eigen::Vector3d> f3(3), t3(3);
    std::vector<std::array<std::size_t, 3>> triplets;
    if (n <= 14) {
      for (std::size_t a = 0; a < n; ++a)
        for (std::size_t b = a + 1; b < n; ++b)
          for (std::size_t c = b + 1; c < n; ++c) triplets.push_back({a, b, c});
    } else {
      std::uint64_t lcg = 0x9E3779B97F4A7C15ull;
      while (triplets.size() < 400) {
        lcg = lcg * 6364136223846793005ull + 1442695040888963407ull;
        const std::size_t a = (lcg >> 33) % n, b = (lcg >> 17) % n, c = (lcg >> 5) % n;
        if (a != b && b != c && a != c) triplets.push_back({a, b, c});
      }
    }
    std::vector<double> sq(n);
    for (const auto& [a, b, c] : triplets) {
      f3 = {from[a], from[b], from[c]};
      t3 = {to[a], to[b], to[c]};
      if ((f3[1] - f3[0]).cross(f3[2] - f3[0]).norm() < 1e-6) continue;
      try {
        const RigidFit fit = fit_rigid(f3, t3);
        for (std::size_t i = 0; i < n; ++i) sq[i] = (to[i] - fit.T_to_from * from[i]).squaredNorm();
        const double med = median_of(sq);
        if (med < best) best = med, t = fit.T_to_from;
      } catch (const GeometryError&) {
      }
    }
    if (!std::isfinite(best)) throw GeometryError("fit_rigid_robust: no non-degenerate triplet");
    // Rousseeuw's finite-sample correction of the LMedS scale.
    scale = std::max(o.noise_floor, kMadToSigma * (1.0 + 5.0 / static_cast<double>(n - 2)) * std::sqrt(best));
    // Tukey biweight IRLS from there.
    for (int it = 0; it < 4; ++it) {
      r = residuals(t, from, to);
      const double c4 = 4.685 * scale;
      std::vector<double> w(n);
      std::size_t used = 0;
      for (std::size_t i = 0; i < n; ++i) {
        const double u = r[i] / c4;
        w[i] = u < 1.0 ? w0[i] * (1 - u * u) * (1 - u * u) : 0.0;
        used += w[i] > 0.0;
      }
      if (used < 3) break;
      try {
        t = fit_rigid(from, to, w).T_to_from;
      } catch (const GeometryError&) {
        break;
      }
    }
    r = residuals(t, from, to);
  }
  // Inliers, then a plain weighted least-squares fit on them (full efficiency).
  out.inlier.assign(n, false);
  std::vector<double> w(n, 0.0);
  for (std::size_t i = 0; i < n; ++i)
    if (r[i] <= o.outlier_sigmas * scale) out.inlier[i] = true, w[i] = w0[i], ++out.inliers;
  if (out.inliers < 3) throw GeometryError("fit_rigid_robust: fewer than 3 features agree");
  const RigidFit fit = fit_rigid(from, to, w);
  out.T_to_from = fit.T_to_from;
  out.rms = fit.rms;
  out.scale = scale;
  return out;
}

}  // namespace dentmark::track
