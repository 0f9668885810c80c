// End to end on what a scanner sees besides the panel: walls and floors behind it, stray
// points far off, folds and crease-shaped dents on small patches.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <random>
#include <set>
#include <tuple>
#include <vector>

#include "dentmark/host/detect/detector.h"
#include "dentmark/host/ingest/cloud_mesher.h"
#include "dentmark/host/report/defects_json.h"
#include "dentmark/host/report/evaluate.h"
#include "dentmark/host/report/pictures.h"
#include "dentmark/host/report/scan_truth.h"
#include "dentmark/sim/scan/sls_scan.h"
#include "detect_scans.h"

namespace dentmark {
namespace {

using namespace detect_test;

// A cols x rows grid of samples 'spacing' apart, 0.8 m before the sensor plus
// height(x, y) (away from it) and 15 µm of noise, meshed.
ingest::Mesh noisy_patch(int cols, int rows, double spacing,
                         const std::function<double(double, double)>& height, std::uint64_t seed) {
  ingest::Mesh patch;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 1.5e-5);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const double x = c * spacing, y = r * spacing;
      patch.vertices.emplace_back(x, y, 0.8 + height(x, y) + noise(rng));
    }
  add_grid_triangles(patch, rows, cols);
  return patch;
}

// A defect planted 'across' (m) from a line or fold at 'at' (map plane) is reported within
// 'reach' of it, of its kind, and its height within 'tolerance'.
void expect_reported(const detect::Detection& det, const Eigen::Vector2d& at, double reach, double height,
                     double tolerance, double across) {
  const auto found = std::find_if(det.defects.begin(), det.defects.end(), [&](const auto& f) {
    return (f.defect.position.template head<2>() - at).norm() < reach;
  });
  ASSERT_NE(found, det.defects.end()) << "defect " << across * 1e3 << " mm from the line";
  EXPECT_EQ(found->defect.defect_class,
            height < 0 ? protocol::DefectClass::kDent : protocol::DefectClass::kBump)
      << "defect " << across * 1e3 << " mm from the line";
  EXPECT_NEAR(found->defect.height, height, tolerance) << "defect " << across * 1e3 << " mm from the line";
}

TEST(Detect, ACreaseShapedDentIsReadToItsFloor) {
  // A long narrow dent (a crease from a sharp edge: 40 x 6 mm, cos² across, flat along
  // with cos² ends) and the same as a bump, at 0.4 mm and 15 µm. Their apex was fitted
  // over a disc of the half-height area's radius, 6 mm, twice the trough's half-height
  // width: it reached the panel on both sides and read 0.2 mm as 0.15 (another
  // generator's roofs, 22-28 % short, 0 of 7 within tolerance).
  struct Crease {
    Eigen::Vector2d centre;
    double angle, height;
  };
  const Crease creases[] = {{{0.04, 0.05}, 0.5, -2e-4}, {{0.12, 0.05}, 2.0, 2e-4}};
  const auto crease_at = [&](double x, double y) {
    double z = 0.0;
    for (const Crease& c : creases) {
      const Eigen::Vector2d d = Eigen::Rotation2Dd(-c.angle) * (Eigen::Vector2d(x, y) - c.centre);
      const double across =
          std::abs(d.y()) < 0.003 ? std::pow(std::cos(std::numbers::pi * d.y() / 0.006), 2) : 0.0;
      const double end = std::max(0.0, std::abs(d.x()) - 0.017);
      z += c.height * across * (end < 0.003 ? std::pow(std::cos(std::numbers::pi * end / 0.006), 2) : 0.0);
    }
    return z;
  };
  // A dent is deeper: away from the sensor at the origin.
  const ingest::Mesh patch = noisy_patch(
      401, 251, 0.0004, [&](double x, double y) { return -crease_at(x, y); }, 11);
  const detect::Detection det = detect::detect(patch, detect::DetectConfig{});
  ASSERT_EQ(det.defects.size(), 2u);
  for (const Crease& c : creases) {
    const auto found = std::find_if(det.defects.begin(), det.defects.end(), [&](const auto& f) {
      return (f.defect.position.template head<2>() - c.centre).norm() < 0.005;
    });
    ASSERT_NE(found, det.defects.end()) << "crease at angle " << c.angle;
    EXPECT_EQ(found->defect.defect_class,
              c.height < 0 ? protocol::DefectClass::kDent : protocol::DefectClass::kBump);
    EXPECT_NEAR(found->defect.height, c.height, 0.1 * std::abs(c.height)) << "crease at angle " << c.angle;
  }
}

TEST(Detect, DefectsBesideASharpFoldAreFoundAndTheFoldIsNot) {
  // A character line: a 0.2 rad fold rounded at 2 mm, at 30° across the map, 0.5 mm and
  // 15 µm, with dents and bumps 16-26 mm from it on both sides. Every window across the
  // fold left a band as wide as itself, which swallowed them (an independent generator's
  // hoods: 26 of 60 found); the fits from the windows beside each pixel leave only the
  // fold's line, a design feature.
  const Eigen::Vector2d along(std::cos(0.52), std::sin(0.52)), across(-along.y(), along.x());
  const Eigen::Vector2d centre(0.15, 0.10);
  struct Planted {
    double s, t, diameter, height;  // along and across the fold from the centre (m)
  };
  const Planted planted[] = {{-0.10, 0.016, 0.010, -1.5e-4}, {-0.06, -0.018, 0.012, 1e-4},
                             {-0.02, 0.020, 0.014, -8e-5},   {0.02, -0.022, 0.010, 2e-4},
                             {0.06, 0.024, 0.012, 1.2e-4},   {0.10, -0.026, 0.014, -1e-4}};
  const auto height_at = [&](double x, double y) {
    const Eigen::Vector2d p = Eigen::Vector2d(x, y) - centre;
    // A hyperbola: slopes of -0.1 and +0.1 either side, a 2 mm radius where they meet.
    double z = 0.1 * std::sqrt(std::pow(p.dot(across), 2) + 0.0002 * 0.0002);
    for (const Planted& d : planted) {
      const double r = (p - d.s * along - d.t * across).norm();
      if (r < 0.5 * d.diameter) z -= d.height * std::pow(std::cos(std::numbers::pi * r / d.diameter), 2);
    }
    return z;  // a bump is towards the sensor at the origin: less deep
  };
  const ingest::Mesh patch = noisy_patch(601, 401, 0.0005, height_at, 17);
  const detect::Detection det = detect::detect(patch, detect::DetectConfig{});
  EXPECT_EQ(det.defects.size(), std::size(planted));
  for (const Planted& d : planted)
    expect_reported(det, centre + d.s * along + d.t * across, 0.001, d.height,
                    std::max(1e-5, 0.1 * std::abs(d.height)), d.t);
  // The fold itself is a design feature, never a defect.
  bool fold_seen = false;
  for (const auto& f : det.features)
    fold_seen = fold_seen || (f.defect.defect_class == protocol::DefectClass::kDesignFeature &&
                              std::abs((f.defect.position.template head<2>() - centre).dot(across)) < 0.004);
  EXPECT_TRUE(fold_seen);
}

// A character line as a stamping leaves it: a 3 mm step rising smoothly over 12 mm, at
// 30° across the map, with dents and bumps on it and 6-9 mm (rim to the step's footprint)
// beside it, sampled every 0.5 mm with 15 µm of noise.
struct CharacterLinePatch {
  struct Planted {
    double s, t, diameter, height;  // along and across the line from the centre (m)
  };
  static constexpr double kStep = 0.003, kWidth = 0.012;
  const Eigen::Vector2d along{std::cos(0.52), std::sin(0.52)}, across{-along.y(), along.x()};
  const Eigen::Vector2d centre{0.15, 0.10};
  std::vector<Planted> planted{{-0.08, 0.0, 0.016, -3e-4},
                               {-0.02, 0.0, 0.014, 2e-4},
                               {0.05, 0.006 + 0.010 + 0.006, 0.020, -2e-4},
                               {0.10, -(0.006 + 0.007 + 0.009), 0.014, 2.5e-4}};

  ingest::Mesh mesh() const {
    const auto height_at = [&](double x, double y) {
      const Eigen::Vector2d p = Eigen::Vector2d(x, y) - centre;
      const double t = p.dot(across);
      double z = t <= -0.5 * kWidth  ? 0.0
                 : t >= 0.5 * kWidth ? kStep
                                     : kStep * 0.5 * (1.0 + std::sin(std::numbers::pi * t / kWidth));
      for (const Planted& d : planted) {
        const double r = (p - d.s * along - d.t * across).norm();
        if (r < 0.5 * d.diameter) z += d.height * std::pow(std::cos(std::numbers::pi * r / d.diameter), 2);
      }
      return -z;  // towards the sensor at the origin: the line stands up, a bump is less deep
    };
    return noisy_patch(601, 401, 0.0005, height_at, 23);
  }
  Eigen::Vector2d at(const Planted& d) const { return centre + d.s * along + d.t * across; }
  bool near(const detect::Finding& f, const Planted& d) const {
    return (f.defect.position.template head<2>() - at(d)).norm() < 0.003;
  }
  // How many planted defects det reports: within 3 mm, of their kind, height within 25 %.
  int count_reported(const detect::Detection& det) const {
    int n = 0;
    for (const Planted& d : planted)
      n += std::any_of(det.defects.begin(), det.defects.end(), [&](const detect::Finding& f) {
        return near(f, d) && (f.defect.height < 0) == (d.height < 0) &&
               std::abs(f.defect.height - d.height) <= 0.25 * std::abs(d.height);
      });
    return n;
  }
  // Each planted defect reported, and nothing else.
  void expect_found_alone(const detect::Detection& det) const {
    for (const Planted& d : planted)
      expect_reported(det, at(d), 0.003, d.height, 0.25 * std::abs(d.height), d.t);
    EXPECT_EQ(det.defects.size(), planted.size());
    for (const auto& f : det.defects) {
      const bool planted_here =
          std::any_of(planted.begin(), planted.end(), [&](const Planted& d) { return near(f, d); });
      EXPECT_TRUE(planted_here) << "false " << report::class_name(f.defect.defect_class) << " "
                                << 1e3 * f.defect.diameter << " mm, " << 1e3 * f.defect.height << " mm at "
                                << 1e3 * f.defect.position.transpose() << " mm (" << f.reason << ")";
    }
  }
};

detect::DetectConfig along_features_on() {
  detect::DetectConfig cfg;
  cfg.along_features = true;
  return cfg;
}

TEST(Detect, DefectsOnAndBesideASmoothCharacterLineAreFoundAlongIt) {
  // The reference follows the step only roughly and leaves a band along it; each of
  // these defects is a deviation from the line's own profile along its length
  // (along_features).
  const CharacterLinePatch line;
  line.expect_found_alone(detect::detect(line.mesh(), along_features_on()));
}

TEST(Detect, ADefectAcrossALinesFlankIsReportedOnce) {
  // Wide dents and bumps centred on the flank's steep middle, where the profile along the
  // line is least sure: the candidates there are cut in two along the line, and each half
  // read as a defect of its own.
  CharacterLinePatch line;
  line.planted = {{-0.08, 0.0, 0.024, -2.5e-4}, {0.0, 0.002, 0.025, 3e-4}, {0.08, -0.002, 0.022, -2e-4}};
  line.expect_found_alone(detect::detect(line.mesh(), along_features_on()));
}

// A door of `scripts/eval-detect`'s features class (its options for the project's
// generator): 16 defects 4-35 mm beside the handle, crease, border and window.
sim::scan::ScanOptions features_class_door(std::uint64_t seed) {
  sim::scan::ScanOptions o;
  o.seed = seed;
  o.shape.width = 0.9, o.shape.height = 0.7;
  o.spacing = 0.0006, o.defects = 0;
  o.near_features = {0.004, 0.009, 0.018, 0.035};
  o.min_diameter = 0.009, o.max_diameter = 0.025, o.min_depth = 1e-4, o.max_depth = 1e-3;
  return o;
}

TEST(Detect, NoFalseDefectsAlongAHandlesRim) {
  if (kSanitized) GTEST_SKIP() << "2 doors through the along stage: run by the native preset";
  // Doors of `scripts/eval-detect`'s features class (seeds 17 and 18): 16 defects 4-35 mm
  // beside the handle, crease, border and window. Round a handle's ends the profiles
  // along it are uncertain (the flanks disagree), and a box mean that reached from there
  // into pixels with a sure profile or none took the residual of that stretch with it:
  // tested against its own pixel's uncertainty alone, it gave three false defects on the
  // first door.
  for (const std::uint64_t seed : {17u, 18u}) {
    const ScanRun r = run(features_class_door(seed), {}, along_features_on());
    EXPECT_EQ(r.eval.false_alarms, 0) << "seed " << seed;
    EXPECT_GE(r.eval.matched, r.eval.truth - 2) << "seed " << seed;
  }
}

TEST(Detect, ADefectBesideACreaseLeavesNoGhostBesideIt) {
  if (kSanitized) GTEST_SKIP() << "a door through the along stage: run by the native preset";
  // The features class's door 8: a 0.9 mm deep dent 4 mm from the crease. Its gradients
  // turned the direction of the crease beside it by ~20 degrees, more than the refinement
  // reaches, and the profile across the crease left a 0.17 mm false bump 10 mm from the
  // dent. Found in the first run, the dent has no say in the direction in the second.
  const ScanRun r = run(features_class_door(8), {}, along_features_on());
  EXPECT_EQ(r.eval.false_alarms, 0);
  EXPECT_GE(r.eval.matched, r.eval.truth - 2);
}

TEST(Detect, TheFootOfAHandlesCornerIsNoBump) {
  if (kSanitized) GTEST_SKIP() << "a door through the along stage: run by the native preset";
  // The features class's door 13. Where the handle's wall turns at its end, the foot's own
  // rounding stands 0.9 mm out of a profile along the rim, which runs through flat
  // flanks; a piece whose peak lies only there is no defect.
  const ScanRun r = run(features_class_door(13), {}, along_features_on());
  EXPECT_EQ(r.eval.false_alarms, 0);
  EXPECT_GE(r.eval.matched, r.eval.truth - 2);
}

TEST(Detect, NoSpecksAlongACharacterLinesCurvedShoulders) {
  if (kSanitized) GTEST_SKIP() << "a door through the along stage: run by the native preset";
  // `scripts/eval-detect`'s lines class, the project's door 5: two character lines
  // across the door (2.8 and -2.6 mm steps over 12 mm), a defect on each and 4-35 mm
  // beside them. A plane through a pixel's 3 x 3 mean points is off by the surface's
  // curvature times how far those points lie from the centre, which changes with the
  // sampling's phase in the pixel grid: with the planes' heights the profiles along the
  // lines read one to three 44-56 um specks 6-7 mm across. The quadrics' read none.
  sim::scan::ScanOptions o;
  o.seed = 5;
  o.shape.width = 0.9, o.shape.height = 0.7;
  o.shape.crease = o.shape.handle = o.shape.window = false;
  for (const auto& [y, step] : {std::pair{0.25, 0.0028}, std::pair{0.6, -0.0026}}) {
    sim::scan::CharacterLine l;
    l.point = {0.5 * o.shape.width, y * o.shape.height};
    l.angle = 0.0, l.step = step, l.width = 0.012;
    o.shape.lines.push_back(l);
  }
  o.spacing = 0.0006, o.defects = 0;
  o.near_lines = {-1.0, -1.0, 0.004, 0.009, 0.018, 0.035};
  o.min_diameter = 0.009, o.max_diameter = 0.025, o.min_depth = 1e-4, o.max_depth = 1e-3;
  const ScanRun r = run(o, {}, along_features_on());
  EXPECT_EQ(r.eval.false_alarms, 0);
  EXPECT_EQ(r.eval.matched, r.eval.truth);
}

TEST(Detect, FlyingPixelsOnACharacterLineRaiseFewDefectsAlongIt) {
  // (One patch runs the same code under the sanitizer:
  // DefectsOnAndBesideASmoothCharacterLineAreFoundAlongIt.)
  if (kSanitized)
    GTEST_SKIP() << "8 patches through the along stage, over 15 min there: run by the native preset";
  // 3 samples in 1000 thrown 1-10 mm along their rays, either way, on 8 patches. A thrown
  // sample moves its pixel's mean point by up to millimetres, and the heights of every
  // pixel whose plane or profile takes it in; its needle triangles pull a neighbouring
  // pixel too. With such pixels left out of the heights (spikes, and pixels off the plane
  // of their neighbours less one far off it), all 32 planted defects are reported (within
  // 3 mm, of their kind, height within 25 %) with 1 other finding (false, or a planted
  // one's height off). Testing each pixel against all 8 neighbours gave 28 and 11; with
  // no thrown pixel left out, 10 and 64, 0.04-1.5 mm high.
  const CharacterLinePatch line;
  int reported = 0, false_defects = 0;
  for (std::uint64_t seed = 5; seed <= 12; ++seed) {
    ingest::Mesh mesh = line.mesh();
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u01(0.0, 1.0);
    for (auto& v : mesh.vertices)
      if (u01(rng) < 3e-3) {
        const double throw_m = (u01(rng) < 0.5 ? -1.0 : 1.0) * (0.001 + 0.009 * u01(rng));
        v *= static_cast<float>(1.0 + throw_m / v.norm());
      }
    const detect::Detection det = detect::detect(mesh, along_features_on());
    const int found = line.count_reported(det);
    reported += found;
    false_defects += static_cast<int>(det.defects.size()) - found;
  }
  EXPECT_GE(reported, 30);
  EXPECT_LE(false_defects, 4);
}

TEST(Detect, AWallFarBehindThePanelIsLeftOut) {
  // The wall surrounded the panel on the map, a step of half a metre behind it, and
  // showed through every pixel the panel left empty: here 1 of the 5 defects was lost and
  // 98 false alarms made. It is left out now; so is a floor at an angle.
  for (const bool floor : {false, true}) {
    double wall_area = 0.0;
    const ScanRun r =
        run(small_door(3), [&](ingest::Mesh& mesh) { wall_area = add_wall_behind(mesh, floor, 800); });
    EXPECT_EQ(r.eval.matched, 5) << (floor ? "floor" : "wall");
    EXPECT_EQ(r.eval.false_alarms, 0) << (floor ? "floor" : "wall");
    EXPECT_GT(r.det.stats.background_area, 0.9 * wall_area) << (floor ? "floor" : "wall");
    EXPECT_LT(r.det.stats.background_area, 1.2 * wall_area) << (floor ? "floor" : "wall");
  }
}

// Adds a wall at height z_at(x, y), half x half metres round the sensor's axis with
// samples `step` apart and 20 um noise, seen right up to the panel's silhouette (hidden
// only where a panel's vertex lies on the ray within 4 mm). Returns the wall's area.
double add_wall_to_the_silhouette(ingest::Mesh& mesh, const std::function<double(double, double)>& z_at,
                                  double step, double half) {
  const double cell = 0.002;  // of the panel's shadow, in x / z and y / z
  std::set<std::pair<int, int>> shadow;
  for (const Eigen::Vector3f& v : mesh.vertices)
    shadow.insert({static_cast<int>(std::floor(v.x() / v.z() / cell)),
                   static_cast<int>(std::floor(v.y() / v.z() / cell))});
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, 2e-5);
  const int n = static_cast<int>(2 * half / step);
  std::vector<std::int64_t> index(static_cast<std::size_t>(n * n), -1);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      const double x = step * (c - n / 2), y = step * (r - n / 2), z = z_at(x, y) + noise(rng);
      const int gx = static_cast<int>(std::floor(x / z / cell)),
                gy = static_cast<int>(std::floor(y / z / cell));
      bool hidden = false;
      for (int a = -1; a <= 1; ++a)
        for (int b = -1; b <= 1; ++b) hidden = hidden || shadow.count({gx + a, gy + b}) > 0;
      if (hidden) continue;
      index[static_cast<std::size_t>(r * n + c)] = static_cast<std::int64_t>(mesh.vertices.size());
      mesh.vertices.emplace_back(x, y, z);
    }
  return add_seen_grid_triangles(mesh, index, n, step);
}

TEST(Detect, APanelBeforeAWallThatFillsTheViewIsThePanel) {
  // A 0.5 x 0.4 m panel 5 cm before a wall 1.35 m square (upright and sloping), seen
  // round it up to its silhouette: the sensor sees the wall over five times as large as
  // the panel, and took the wall for the panel and left the panel out (0 of 5 found).
  const sim::scan::SynthScan door = sim::scan::synthesize_scan(small_door(3));
  for (const double slope : {0.0, 0.4}) {
    double behind = -1.0;  // the wall's plane through the panel's farthest point
    for (const Eigen::Vector3f& v : door.vertices) behind = std::max(behind, v.z() - slope * v.y());
    double wall_area = 0.0;
    const ScanRun r = run(small_door(3), [&](ingest::Mesh& mesh) {
      wall_area = add_wall_to_the_silhouette(
          mesh, [&](double, double y) { return behind + 0.05 + slope * y; }, 0.001, 0.675);
    });
    EXPECT_EQ(r.eval.matched, 5) << "slope " << slope;
    EXPECT_EQ(r.eval.false_alarms, 0) << "slope " << slope;
    EXPECT_GT(r.det.stats.background_area, 0.9 * wall_area) << "slope " << slope;
    EXPECT_LT(r.det.stats.background_area, 1.2 * wall_area) << "slope " << slope;
  }
}

TEST(Detect, TheSpacingIsThePanelsNotTheWallsBehindIt) {
  // A wall 1.1 m behind the panel with more samples than the panel, 2.5 times as far
  // apart (as a camera sees it): the scan's median spacing was the wall's, the finest
  // node 3 mm, and a map of 3 mm pixels lost the 5 mm defects. Without noise the outliers'
  // spikes also read as bumps 5 mm across there (the other generator's SW25: 8 false
  // alarms). The spacing is measured again on the panel, and the octree built at that.
  sim::scan::ScanOptions o;
  o.seed = 5;
  o.shape.width = 0.3;
  o.shape.height = 0.25;
  o.spacing = 0.0006;
  o.defects = 0;
  o.shape.window = false;
  o.shape.crease = false;
  o.shape.handle = false;
  o.noise = 0.0;
  o.outlier_fraction = 1e-3;
  o.planted = {{{0.07, 0.07}, 0.006, -1e-4}, {{0.20, 0.08}, 0.010, 5e-5}, {{0.13, 0.17}, 0.005, 1e-4}};
  const ScanRun r = run(o, [](ingest::Mesh& mesh) { add_wall_behind(mesh, false, 720, 2.0); });
  EXPECT_NEAR(r.det.stats.spacing, 0.0006, 0.0001);
  EXPECT_EQ(r.eval.matched, 3);
  EXPECT_EQ(r.eval.false_alarms, 0);
  EXPECT_LT(r.eval.max_position_error, 0.001);
}

TEST(Detect, StrayPointsFarOffThePanelAreLeftOut) {
  // An outlier vertex tens or hundreds of metres off, meshed to the panel as a spike or
  // not used by any face. Once a spike 304 m off stretched the height map to 23 GB (and
  // tilted its plane: the spike's triangles outweighed the panel); a vertex 100 m off
  // made the octree too deep for 1 mm nodes and the scan was refused.
  sim::scan::ScanOptions o = small_door(61);
  const sim::scan::SynthScan scan = sim::scan::synthesize_scan(o);
  const report::TruthFile truth = report::truth_from_scan(scan);
  const auto detect_with = [&](const std::vector<Eigen::Vector3f>& extra, int spikes) {
    ingest::Mesh mesh;
    mesh.vertices = scan.vertices;
    mesh.triangles = scan.triangles;
    for (const auto& p : extra) {
      const auto k = static_cast<std::uint32_t>(mesh.vertices.size());
      mesh.vertices.push_back(p);
      for (int i = 0; i < spikes; ++i) {  // a spike: triangles from the stray vertex to the panel
        const auto& t = scan.triangles[static_cast<std::size_t>(1000 + 7919 * (k % 13) + i)];
        mesh.triangles.push_back({t[0], t[1], k});
      }
    }
    return detect::detect(mesh, detect::DetectConfig{});
  };
  const detect::Detection clean = detect_with({}, 0);
  const auto scored = [&](const detect::Detection& det) {
    report::DefectsFile found;
    for (const auto& f : det.defects)
      found.defects.push_back({report::class_name(f.defect.defect_class), f.defect});
    return report::evaluate(truth, found);
  };
  ASSERT_EQ(scored(clean).matched, 5);
  struct Case {
    const char* what;
    std::vector<Eigen::Vector3f> extra;
    int spikes;
    std::size_t stray;
  };
  for (const Case& c : {Case{"spikes 30 m off (kept in the octree, off the map)",
                             {{0.1f, 30.0f, 0.9f}, {30.0f, 0.1f, 9.0f}},
                             3,
                             0},
                        Case{"spikes 304 m off", {{0.08f, 304.0f, 0.9f}, {0.04f, 0.04f, 264.0f}}, 3, 6},
                        Case{"an unused vertex 100 m off", {{100.0f, 0.0f, 0.0f}}, 0, 0}}) {
    SCOPED_TRACE(c.what);
    const detect::Detection det = detect_with(c.extra, c.spikes);
    const report::Evaluation e = scored(det);
    EXPECT_EQ(e.matched, 5);
    EXPECT_EQ(e.false_alarms, 0);
    EXPECT_EQ(det.stats.stray_triangles, c.stray);
    EXPECT_LE(det.map.size(), clean.map.size() + clean.map.size() / 10);
    EXPECT_GT(std::abs(det.map.axes.row(2).dot(clean.map.axes.row(2))), 0.9999);  // the panel's plane
  }
}

}  // namespace
}  // namespace dentmark
