// Reference surface: reproduces what it can represent, is not pulled by what is left out,
// and a refit after some weights change equals a fit from scratch to the last bit.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <numbers>
#include <random>
#include <utility>

#include "dentmark/host/detect/reference_surface.h"

namespace dentmark::detect {
namespace {

// A 0.2 x 0.15 m height map (or cols x rows) at 1 mm pixels with w = f(u, v), every pixel
// weighted 1, centred on (0, 0).
HeightMap map_of(const std::function<double(double, double)>& f, int cols = 200, int rows = 150) {
  HeightMap map;
  map.pixel = 0.001;
  map.cols = cols, map.rows = rows;
  map.u0 = -0.0005 * cols, map.v0 = -0.0005 * rows;
  const std::size_t n = map.size();
  map.weight.assign(n, 1.0f), map.cos_tilt.assign(n, 1.0f);
  map.u.resize(n), map.v.resize(n), map.w.resize(n);
  for (int r = 0; r < map.rows; ++r)
    for (int c = 0; c < map.cols; ++c) {
      const std::size_t k = static_cast<std::size_t>(r) * map.cols + c;
      map.u[k] = static_cast<float>(map.u0 + (c + 0.3) * map.pixel);  // off-centre samples
      map.v[k] = static_cast<float>(map.v0 + (r + 0.6) * map.pixel);
      map.w[k] = static_cast<float>(f(map.u[k], map.v[k]));
    }
  return map;
}

double bump(double u, double v) {  // 0.2 mm high, 10 mm across, at (0.02, 0.01)
  const double d2 = (u - 0.02) * (u - 0.02) + (v - 0.01) * (v - 0.01);
  return 0.0002 * std::exp(-d2 / (2 * 0.0025 * 0.0025));
}

double panel(double u, double v) {
  return 0.05 + 0.3 * u - 0.2 * v + 0.8 * u * u - 0.5 * u * v + 0.4 * v * v;
}

TEST(ReferenceSurface, ReproducesAQuadraticPanel) {
  const HeightMap map = map_of(panel);
  ReferenceSurface surface(map, 0.064);
  const std::vector<float>& ref = surface.fit(map.weight);
  for (std::size_t k = 0; k < map.size(); ++k) ASSERT_NEAR(ref[k], map.w[k], 2e-7) << k;
}

TEST(ReferenceSurface, FollowsAPanelThatTurnsTooFastForAQuadraticOverTheWindow) {
  // A fender's side: a cylinder of 0.33 m radius seen at 14-58 degrees (across the 64 mm
  // window the slope turns by up to 20 degrees). A quadratic over the whole window misses
  // its cubic term: by 57 µm where the slope is under 50 degrees, 7 µm under 30. Over
  // half the window, which the fit takes where that leaves a far smaller residual: 6 and
  // 1 µm.
  const double R = 0.33;
  const auto fender = [R](double u, double) { return std::sqrt(R * R - (u + 0.18) * (u + 0.18)); };
  const HeightMap map = map_of(fender);
  ReferenceSurface surface(map, 0.064);
  const std::vector<float>& ref = surface.fit(map.weight);
  for (const auto& [degrees, bound] : {std::pair{30.0, 2e-6}, std::pair{50.0, 1e-5}}) {
    double worst = 0.0;
    for (int r = 10; r < map.rows - 10; ++r)
      for (int c = 10; c < map.cols - 10; ++c) {
        const std::size_t k = static_cast<std::size_t>(r) * map.cols + c;
        if (std::asin((map.u[k] + 0.18) / R) > degrees * std::numbers::pi / 180.0) continue;
        worst = std::max(worst, std::abs(static_cast<double>(ref[k]) - map.w[k]));
      }
    EXPECT_LT(worst, bound) << "slopes under " << degrees << " degrees";
  }
}

TEST(ReferenceSurface, HeightAtAnyPointIsThePixelsBlend) {
  // At a pixel's own point it is the pixel's value; between pixels it follows the panel
  // (the vertex samples of a defect are measured against it).
  const HeightMap map = map_of(panel);
  ReferenceSurface surface(map, 0.064);
  const std::vector<float>& ref = surface.fit(map.weight);
  for (std::size_t k = 0; k < map.size(); k += 37)
    ASSERT_NEAR(surface.height_at(map.u[k], map.v[k]), ref[k], 2e-7) << k;
  for (double u = -0.095; u < 0.095; u += 0.0073)
    for (double v = -0.07; v < 0.07; v += 0.0061) ASSERT_NEAR(surface.height_at(u, v), panel(u, v), 2e-7);
  const HeightMap steep =
      map_of([](double u, double) { return std::sqrt(0.33 * 0.33 - (u + 0.18) * (u + 0.18)); });
  ReferenceSurface fender(steep, 0.064);
  fender.fit(steep.weight);
  for (double u = -0.08; u < 0.0; u += 0.0037)  // slopes 16-33 degrees
    EXPECT_NEAR(fender.height_at(u, 0.01), std::sqrt(0.33 * 0.33 - (u + 0.18) * (u + 0.18)), 2e-6) << u;
}

TEST(ReferenceSurface, PixelsLeftOutDoNotPullIt) {
  const HeightMap map = map_of([](double u, double v) { return panel(u, v) + bump(u, v); });
  ReferenceSurface surface(map, 0.064);
  const std::size_t apex = static_cast<std::size_t>(85) * map.cols + 120;  // (0.02, 0.01)
  const float pulled = surface.fit(map.weight)[apex];
  EXPECT_GT(pulled - panel(map.u[apex], map.v[apex]), 3e-6);  // the bump pulls a fit over it (5 µm)
  std::vector<float> weights = map.weight;
  for (std::size_t k = 0; k < map.size(); ++k)
    if (bump(map.u[k], map.v[k]) > 1e-7) weights[k] = 0.0f;
  const float clean = surface.fit(weights)[apex];
  EXPECT_NEAR(clean, panel(map.u[apex], map.v[apex]), 3e-7);
}

TEST(ReferenceSurface, ARefitEqualsAFitFromScratch) {
  const HeightMap map = map_of([](double u, double v) {
    return panel(u, v) + bump(u, v) + 0.00002 * std::sin(300 * u) * std::cos(200 * v);
  });
  std::vector<float> weights = map.weight;
  for (std::size_t k = 0; k < map.size(); k += 7) weights[k] = 0.5f;  // uneven, some empty
  for (std::size_t k = 0; k < map.size(); k += 13) weights[k] = 0.0f;
  ReferenceSurface incremental(map, 0.064);
  incremental.fit(weights);
  // Leave out two patches, then one of them again.
  for (int step = 0; step < 2; ++step) {
    for (int r = 70; r < 100; ++r)
      for (int c = step ? 20 : 110; c < (step ? 35 : 130); ++c)
        weights[static_cast<std::size_t>(r) * map.cols + c] = 0;
    if (step) weights[static_cast<std::size_t>(80) * map.cols + 120] = 1.0f;
    const std::vector<float>& refit = incremental.fit(weights);
    ReferenceSurface scratch(map, 0.064);
    const std::vector<float>& fresh = scratch.fit(weights);
    ASSERT_EQ(refit.size(), fresh.size());
    EXPECT_EQ(std::memcmp(refit.data(), fresh.data(), refit.size() * sizeof(float)), 0) << "step " << step;
  }
  // And the refit did change something.
  ReferenceSurface first(map, 0.064);
  std::vector<float> before = map.weight;
  EXPECT_NE(
      std::memcmp(first.fit(before).data(), incremental.fit(weights).data(), map.size() * sizeof(float)), 0);
}

TEST(ReferenceSurface, AWindowMostlyLeftOutWidensAndARefitStillEqualsAFitFromScratch) {
  // A 100 x 100 mm patch left out (a handle and its margins): the 64 mm windows inside
  // hold nothing, those at its edge a sliver, which extrapolates. Windows under a
  // quarter full take twice the window; inside the patch the reference still follows
  // the panel, and refits equal fits from scratch.
  const auto ripple = [](double u, double v) {
    return panel(u, v) + 2e-6 * std::sin(300 * u) * std::cos(200 * v);
  };
  const HeightMap map = map_of(ripple);
  std::vector<float> weights = map.weight;
  ReferenceSurface incremental(map, 0.064);
  incremental.fit(weights);
  for (int step = 0; step < 2; ++step) {
    for (int r = 25; r < 125; ++r)
      for (int c = 50; c < 150; ++c)
        weights[static_cast<std::size_t>(r) * map.cols + c] = step == 1 && c >= 120 ? map.weight[0] : 0.0f;
    const std::vector<float>& refit = incremental.fit(weights);
    ReferenceSurface scratch(map, 0.064);
    const std::vector<float>& fresh = scratch.fit(weights);
    EXPECT_EQ(std::memcmp(refit.data(), fresh.data(), refit.size() * sizeof(float)), 0) << "step " << step;
    double worst = 0.0;
    for (int r = 25; r < 125; ++r)
      for (int c = 50; c < 150; ++c) {
        const std::size_t k = static_cast<std::size_t>(r) * map.cols + c;
        ASSERT_TRUE(std::isfinite(refit[k])) << r << " " << c;
        worst = std::max(worst, std::abs(refit[k] - ripple(map.u[k], map.v[k])));
      }
    EXPECT_LT(worst, 1e-5) << "step " << step;
  }
}

// A character line: a 0.2 rad fold rounded at 2 mm, at 20 degrees across the map, on the
// quadratic panel, with a little noise.
double fold_distance(double u, double v) {
  return -std::sin(0.35) * (u - 0.01) + std::cos(0.35) * (v + 0.005);
}
double folded(double u, double v) {
  const double t = fold_distance(u, v);
  return panel(u, v) + 0.1 * std::sqrt(t * t + 0.0002 * 0.0002) +
         3e-6 * std::sin(2100 * u) * std::cos(1700 * v);
}

TEST(ReferenceSurface, FollowsBothSidesOfASharpFold) {
  // Every window across the fold fits one quadratic to both sides: a band of tens of µm
  // as wide as the window (the defects in it were lost). Beside the fold the pixels take
  // the fits of the windows on their side: within 3 µm from 3 mm off the line, and the
  // line itself is marked. (A map of 0.4 x 0.3 m: where the map's edge is less than a
  // window from the fold, side windows are few.)
  const HeightMap map = map_of(folded, 400, 300);
  ReferenceSurface surface(map, 0.064);
  const std::vector<float>& ref = surface.fit(map.weight);
  double worst = 0.0;
  for (int r = 40; r < map.rows - 40; ++r)
    for (int c = 40; c < map.cols - 40; ++c) {
      const std::size_t k = static_cast<std::size_t>(r) * map.cols + c;
      if (std::abs(fold_distance(map.u[k], map.v[k])) > 0.003) {
        worst = std::max(worst, std::abs(static_cast<double>(ref[k]) - map.w[k]));
      }
    }
  EXPECT_LT(worst, 6e-6);  // the noise's 3 and the fit's
  const auto& line = surface.fold_lines();
  ASSERT_EQ(line.size(), map.size());
  int on = 0, off = 0;
  for (std::size_t k = 0; k < map.size(); ++k)
    if (line[k]) (std::abs(fold_distance(map.u[k], map.v[k])) < 0.003 ? on : off)++;
  EXPECT_GT(on, 100);  // a fair part of its ~420 mm across the map (detection joins the rest)
  EXPECT_EQ(off, 0);

  // Without the fold pass (a tile's own window only) the band is what it was.
  ReferenceSurface plain(map, 0.064);  // (the same map)
  plain.look_for_folds(false);
  const std::vector<float>& band = plain.fit(map.weight);
  double band_worst = 0.0;
  for (std::size_t k = 0; k < map.size(); ++k)
    if (std::abs(fold_distance(map.u[k], map.v[k])) > 0.015)
      band_worst = std::max(band_worst, std::abs(static_cast<double>(band[k]) - map.w[k]));
  EXPECT_GT(band_worst, 2e-5);
  EXPECT_TRUE(plain.fold_lines().empty());
}

TEST(ReferenceSurface, AFoldedRefitMatchesAFitFromScratch) {
  const HeightMap map = map_of(folded, 400, 300);
  std::vector<float> weights = map.weight;
  ReferenceSurface incremental(map, 0.064);
  incremental.fit(weights);
  for (int r = 60; r < 80; ++r)  // a patch beside the fold left out, as a defect's
    for (int c = 100; c < 115; ++c) weights[static_cast<std::size_t>(r) * map.cols + c] = 0;
  const std::vector<float>& refit = incremental.fit(weights);
  ReferenceSurface scratch(map, 0.064);
  const std::vector<float>& fresh = scratch.fit(weights);
  // The fold pass is redone from the blend every time. (On this map the blend itself
  // differs from a fit from scratch by float rounding in a few pixels far from the
  // patch: the tiles' window sums come from an integral image over the whole map, which
  // the patch changes; the tiles not refitted keep sums rounded the old way.)
  double worst = 0.0;
  for (std::size_t k = 0; k < refit.size(); ++k)
    if (std::isfinite(fresh[k])) worst = std::max(worst, std::abs(static_cast<double>(refit[k]) - fresh[k]));
  EXPECT_LT(worst, 1e-7);
  int differ = 0;
  for (std::size_t k = 0; k < refit.size(); ++k)
    differ += incremental.fold_lines()[k] != scratch.fold_lines()[k];
  EXPECT_LE(differ, 2);
}

TEST(ReferenceSurface, ANoisyFoldIsMarkedAlongItsWholeLength) {
  // A 0.1 rad fold under 40 um of noise per pixel (a coarse, noisy scan): its rounding
  // leaves residuals a few times the noise, which mark its line only in pieces, and the
  // pieces between were reported as dents. Where the fits of the windows on either side
  // intersect, the line is marked whatever the noise: in nearly every column, and only
  // near the fold.
  HeightMap map = map_of(
      [](double u, double v) {
        const double t = fold_distance(u, v);
        return panel(u, v) + 0.05 * std::sqrt(t * t + 0.0005 * 0.0005);
      },
      400, 300);
  std::mt19937 rng(11);
  std::normal_distribution<float> noise(0.0f, 4e-5f);
  for (float& w : map.w) w += noise(rng);
  ReferenceSurface surface(map, 0.064);
  surface.fit(map.weight);
  const auto& line = surface.fold_lines();
  ASSERT_EQ(line.size(), map.size());
  int columns = 0, marked = 0, off = 0;
  for (int c = 60; c < map.cols - 60; ++c) {
    bool near = false, any = false;
    for (int r = 60; r < map.rows - 60; ++r) {
      const std::size_t k = static_cast<std::size_t>(r) * map.cols + c;
      const double t = std::abs(fold_distance(map.u[k], map.v[k]));
      near = near || t < 0.01;
      if (line[k]) (t < 0.003 ? any = true : ++off);
    }
    columns += near, marked += near && any;
  }
  EXPECT_GT(columns, 200);
  EXPECT_GE(marked, 0.95 * columns);
  EXPECT_EQ(off, 0);
}

TEST(ReferenceSurface, ACurvedPanelIsNoFold) {
  // The fender of the test above (a cylinder at 14-58 degrees) turns fast, and the fits
  // on either side of a tile fit better than its own; but their slopes agree.
  const HeightMap map =
      map_of([](double u, double) { return std::sqrt(0.33 * 0.33 - (u + 0.18) * (u + 0.18)); });
  ReferenceSurface surface(map, 0.064);
  surface.fit(map.weight);
  EXPECT_TRUE(surface.fold_lines().empty());
  const HeightMap smooth = map_of(panel);
  ReferenceSurface quadratic(smooth, 0.064);
  quadratic.fit(smooth.weight);
  EXPECT_TRUE(quadratic.fold_lines().empty());
}

}  // namespace
}  // namespace dentmark::detect
