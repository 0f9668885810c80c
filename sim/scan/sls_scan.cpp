#include "dentmark/sim/scan/sls_scan.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <optional>
#include <random>
#include <stdexcept>

namespace dentmark::sim::scan {
namespace {

std::uint64_t splitmix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

std::vector<PlantedDefect> place_defects(const ScanOptions& o, const DoorPanel& probe, std::mt19937_64& rng) {
  std::vector<PlantedDefect> out = o.planted;
  std::uniform_real_distribution<double> ux(0.0, o.shape.width), uy(0.0, o.shape.height), u01(0.0, 1.0);
  for (int k = 0; k < o.defects; ++k) {
    for (int attempt = 0; attempt < 2000; ++attempt) {
      PlantedDefect d;
      d.centre = {ux(rng), uy(rng)};
      d.diameter = o.min_diameter + (o.max_diameter - o.min_diameter) * u01(rng);
      const double mag = o.min_depth * std::pow(o.max_depth / o.min_depth, u01(rng));
      d.height = u01(rng) < 0.5 ? -mag : mag;
      d.rim = o.rim;
      const auto reach = [](const PlantedDefect& p) { return p.rim > 0.0 ? p.diameter : 0.5 * p.diameter; };
      if (probe.feature_distance(d.centre.x(), d.centre.y()) < reach(d) + 0.04) continue;
      bool clear = true;
      for (const auto& e : out)
        if ((e.centre - d.centre).norm() < reach(e) + reach(d) + 0.03) clear = false;
      if (!clear) continue;
      out.push_back(d);
      break;
    }
  }
  return out;
}

// One defect of random size whose rim lies 'gap' from the footprint of 'feature' (a
// negative gap: centred on a character line), clear of every other feature by 25 mm
// and of the defects already placed. Centres start anywhere and are moved along the
// footprint distance's gradient onto the wanted level (a distance field has unit slope).
std::optional<PlantedDefect> place_beside(const ScanOptions& o, const DoorPanel& probe,
                                          const std::string& feature, double gap,
                                          const std::vector<PlantedDefect>& placed, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> ux(0.0, o.shape.width), uy(0.0, o.shape.height), u01(0.0, 1.0);
  const std::vector<std::string> names = probe.feature_names();
  const bool on_line = gap < 0.0;
  for (int attempt = 0; attempt < 4000; ++attempt) {
    PlantedDefect d;
    d.diameter = o.min_diameter + (o.max_diameter - o.min_diameter) * u01(rng);
    const double mag = o.min_depth * std::pow(o.max_depth / o.min_depth, u01(rng));
    d.height = u01(rng) < 0.5 ? -mag : mag;
    const double r = 0.5 * d.diameter;
    Eigen::Vector2d c(ux(rng), uy(rng));
    auto dist = [&](const Eigen::Vector2d& p) { return probe.footprint_distance(feature, p.x(), p.y()); };
    double target = gap + r;
    if (on_line) {
      // The line's centre: the footprint's least distance, -width/2.
      const std::size_t k = static_cast<std::size_t>(std::atoi(feature.c_str() + 4));
      target = -0.5 * o.shape.lines.at(k).width;
    }
    for (int it = 0; it < 6; ++it) {
      constexpr double e = 1e-5;
      const Eigen::Vector2d g((dist(c + Eigen::Vector2d(e, 0)) - dist(c - Eigen::Vector2d(e, 0))) / (2 * e),
                              (dist(c + Eigen::Vector2d(0, e)) - dist(c - Eigen::Vector2d(0, e))) / (2 * e));
      if (!(g.norm() > 0.5)) break;
      c += (target - dist(c)) * g / g.squaredNorm();
    }
    if (std::abs(dist(c) - target) > 2e-4 || !probe.inside(c.x(), c.y())) continue;
    bool clear = true;
    for (const std::string& other : names)
      if (other != feature && probe.footprint_distance(other, c.x(), c.y()) < r + 0.025) clear = false;
    for (const auto& e : placed)
      if ((e.centre - c).norm() < 0.5 * (e.diameter + d.diameter) + 0.015) clear = false;
    if (!clear) continue;
    d.centre = c;
    d.beside = feature;
    d.gap = on_line ? -r : gap;
    return d;
  }
  return std::nullopt;
}

std::vector<PlantedDefect> place_near_features(const ScanOptions& o, const DoorPanel& probe,
                                               std::vector<PlantedDefect> placed, std::mt19937_64& rng) {
  std::vector<std::pair<std::string, double>> jobs;
  for (const std::string& f : probe.feature_names()) {
    const bool line = f.rfind("line", 0) == 0;
    for (double g : line ? o.near_lines : o.near_features) jobs.emplace_back(f, g);
  }
  for (const auto& [feature, gap] : jobs)
    if (std::optional<PlantedDefect> d = place_beside(o, probe, feature, gap, placed, rng))
      placed.push_back(*d);
  return placed;
}

// Through-holes: clear of design features and of the dents and bumps.
std::vector<Eigen::Vector3d> place_holes(const ScanOptions& o, const DoorPanel& panel, std::mt19937_64& rng) {
  std::vector<Eigen::Vector3d> out;  // x, y, diameter
  std::uniform_real_distribution<double> ux(0.0, o.shape.width), uy(0.0, o.shape.height), u01(0.0, 1.0);
  for (int k = 0; k < o.holes; ++k)
    for (int attempt = 0; attempt < 2000; ++attempt) {
      const Eigen::Vector3d h(ux(rng), uy(rng),
                              o.min_hole_diameter + (o.max_hole_diameter - o.min_hole_diameter) * u01(rng));
      if (panel.feature_distance(h.x(), h.y()) < 0.5 * h.z() + 0.04) continue;
      bool clear = true;
      for (const auto& d : panel.defects())
        if ((d.centre - h.head<2>()).norm() < 0.5 * (d.diameter + h.z()) + 0.03) clear = false;
      for (const auto& e : out)
        if ((e.head<2>() - h.head<2>()).norm() < 0.5 * (e.z() + h.z()) + 0.03) clear = false;
      if (!clear) continue;
      out.push_back(h);
      break;
    }
  return out;
}

void check_options(const ScanOptions& o) {
  if (!(o.spacing > 1e-5 && o.spacing < 0.05))
    throw std::invalid_argument("spacing must be in (0.01 mm, 50 mm)");
  if (!(o.noise >= 0.0 && o.noise < 0.01)) throw std::invalid_argument("noise must be in [0, 10 mm)");
  if (o.defects < 0 || o.defects > 200) throw std::invalid_argument("defects must be in [0, 200]");
  if (o.holes < 0 || o.holes > 50) throw std::invalid_argument("holes must be in [0, 50]");
  if (!(o.min_hole_diameter > 0 && o.max_hole_diameter >= o.min_hole_diameter && o.hole_backdrop > 0))
    throw std::invalid_argument("hole sizes and backdrop must be positive and ordered");
  if (!(o.min_diameter > 0 && o.max_diameter >= o.min_diameter && o.min_depth > 0 &&
        o.max_depth >= o.min_depth))
    throw std::invalid_argument("defect size ranges must be positive and ordered");
  if (!(o.rim >= 0.0 && o.rim <= 1.0)) throw std::invalid_argument("rim must be in [0, 1]");
  if (!(o.outlier_fraction >= 0.0 && o.outlier_fraction <= 0.1))
    throw std::invalid_argument("outlier fraction must be in [0, 0.1]");
  for (double g : o.near_features)
    if (!(g >= 0.0 && g < 0.2)) throw std::invalid_argument("gaps beside features must be in [0, 0.2) m");
  for (double g : o.near_lines)
    if (!(g < 0.2)) throw std::invalid_argument("gaps beside character lines must be under 0.2 m");
  for (const CharacterLine& l : o.shape.lines)
    if (!(std::abs(l.step) <= 0.02 && l.width > 0.001 && l.width < 0.1 && std::isfinite(l.angle)))
      throw std::invalid_argument("a character line's step must be within 20 mm, its width in (1, 100) mm");
  if (o.shape.width * o.shape.height / (o.spacing * o.spacing) > 6e7)
    throw std::invalid_argument("scan would exceed 60 M points; raise the spacing");
}

// The sensor and its grid of rays: the sensor at C looks at the panel centre from
// 'standoff', tilted up to 12 degrees; ray (r, c) has the direction (u0 + c step,
// v0 + r step, 1) in 'sls', and the grid covers the panel's corners.
struct SensorGrid {
  Eigen::Vector3d C;            // the sensor, panel frame
  Eigen::Matrix3d R_panel_sls;  // sls axes in the panel frame
  Eigen::Isometry3d T_sls_panel;
  double u0 = 0.0, v0 = 0.0, step = 0.0;
  std::size_t rows = 0, cols = 0;

  Eigen::Vector3d ray_sls(std::size_t r, std::size_t c) const {
    return Eigen::Vector3d(u0 + static_cast<double>(c) * step, v0 + static_cast<double>(r) * step, 1.0)
        .normalized();
  }
};

SensorGrid place_sensor(const ScanOptions& o, const DoorPanel& panel, std::mt19937_64& rng) {
  const double W = o.shape.width, H = o.shape.height;
  std::uniform_real_distribution<double> tilt(-12.0, 12.0);
  double yaw = tilt(rng) * std::numbers::pi / 180.0, pitch = tilt(rng) * std::numbers::pi / 180.0;
  if (o.tilt) yaw = o.tilt->x(), pitch = o.tilt->y();  // (the roll: synthesize_scan)
  const Eigen::Vector3d centre(0.5 * W, 0.5 * H, panel.z_nominal(0.5 * W, 0.5 * H));
  const Eigen::Vector3d back =
      (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitX()))
          .toRotationMatrix() *
      Eigen::Vector3d::UnitZ();
  SensorGrid g;
  g.C = centre + o.standoff * back;
  const Eigen::Vector3d zc = -back;
  const Eigen::Vector3d xc = (Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitX().dot(zc) * zc).normalized();
  const Eigen::Vector3d yc = zc.cross(xc);
  g.R_panel_sls << xc, yc, zc;
  Eigen::Isometry3d T_panel_sls = Eigen::Isometry3d::Identity();
  T_panel_sls.linear() = g.R_panel_sls;
  T_panel_sls.translation() = g.C;
  g.T_sls_panel = T_panel_sls.inverse();

  // Image extent from the panel corners.
  double u0 = 1e9, u1 = -1e9, v0 = 1e9, v1 = -1e9;
  for (double cx : {0.0, W})
    for (double cy : {0.0, H}) {
      const Eigen::Vector3d p = g.T_sls_panel * Eigen::Vector3d(cx, cy, panel.z_nominal(cx, cy));
      u0 = std::min(u0, p.x() / p.z()), u1 = std::max(u1, p.x() / p.z());
      v0 = std::min(v0, p.y() / p.z()), v1 = std::max(v1, p.y() / p.z());
    }
  g.u0 = u0, g.v0 = v0;
  g.step = o.spacing / o.standoff;
  g.cols = static_cast<std::size_t>((u1 - u0) / g.step) + 2;
  g.rows = static_cast<std::size_t>((v1 - v0) / g.step) + 2;
  return g;
}

// Newton's iteration for f(t) = 0 from t; false when it does not converge.
template <class F>
bool newton(F&& f, double& t) {
  for (int it = 0; it < 12; ++it) {
    const double ft = f(t);
    if (std::abs(ft) < 1e-10) return true;
    const double e = 1e-6, df = (f(t + e) - f(t - e)) / (2 * e);
    if (!(std::abs(df) > 1e-6)) return false;
    t -= ft / df;
  }
  return false;
}

// The first sign change of g past a, in 0.5 mm steps up to 0.2 m, then bisected.
template <class F>
std::optional<double> bracket_root(F&& g, double a) {
  double ga = g(a);
  for (double b = a + 0.0005; b < a + 0.2; b += 0.0005) {
    const double gb = g(b);
    if ((ga > 0) != (gb > 0)) {
      for (int it = 0; it < 40; ++it) {
        const double m = 0.5 * (a + b), gm = g(m);
        if ((gm > 0) == (ga > 0))
          a = m, ga = gm;
        else
          b = m;
      }
      return 0.5 * (a + b);
    }
    a = b, ga = gb;
  }
  return std::nullopt;
}

// Where ray d (panel frame) from the sensor meets the skin, or the inner structure
// behind a through-hole; nullopt off the panel.
std::optional<Eigen::Vector3d> cast_ray(const ScanOptions& o, const DoorPanel& panel,
                                        const std::vector<Eigen::Vector3d>& holes, const SensorGrid& g,
                                        const Eigen::Vector3d& d, double& t) {
  const Eigen::Vector3d& C = g.C;
  const double z_centre = panel.z_nominal(0.5 * o.shape.width, 0.5 * o.shape.height);
  auto skin = [&](double s) {
    const Eigen::Vector3d p = C + s * d;
    return p.z() - panel.z(p.x(), p.y());
  };
  // Newton from the nominal plane; bracketing fallback on steep walls.
  t = (z_centre - C.z()) / d.z();
  if (!newton(skin, t)) {
    const std::optional<double> root = bracket_root(skin, (z_centre + 0.04 - C.z()) / d.z());
    if (!root) return std::nullopt;
    t = *root;
  }
  Eigen::Vector3d p = C + t * d;
  if (!panel.inside(p.x(), p.y())) return std::nullopt;
  for (const auto& hole : holes)
    if (std::hypot(p.x() - hole.x(), p.y() - hole.y()) < 0.5 * hole.z()) {
      // Through the hole onto the inner structure behind the skin.
      const bool ok = newton(
          [&](double s) {
            const Eigen::Vector3d q = C + s * d;
            return q.z() - (panel.z_nominal(q.x(), q.y()) - o.hole_backdrop);
          },
          t);
      if (!ok) return std::nullopt;
      p = C + t * d;
      break;
    }
  return p;
}

// The sensor's range image: each ray's point in 'sls', with range noise and outliers,
// or invalid (off the panel, in a dropout). Row r draws from its own seed, so rows can
// run in parallel and the result does not depend on the thread count.
void sample_range_grid(const ScanOptions& o, const DoorPanel& panel,
                       const std::vector<Eigen::Vector3d>& holes, const std::vector<Eigen::Vector3d>& drops,
                       const SensorGrid& g, std::vector<Eigen::Vector3f>& grid,
                       std::vector<std::uint8_t>& valid) {
  grid.assign(g.rows * g.cols, Eigen::Vector3f::Zero());
  valid.assign(g.rows * g.cols, 0);
  const std::uint64_t base_seed = splitmix(o.seed ^ 0xabcdef12345ull);
#pragma omp parallel for schedule(dynamic, 16)
  for (std::int64_t r = 0; r < static_cast<std::int64_t>(g.rows); ++r) {
    std::mt19937_64 rr(splitmix(base_seed + static_cast<std::uint64_t>(r)));
    std::normal_distribution<double> gauss(0.0, 1.0);
    std::uniform_real_distribution<double> u01(0.0, 1.0);
    for (std::size_t c = 0; c < g.cols; ++c) {
      const Eigen::Vector3d dir_sls = g.ray_sls(static_cast<std::size_t>(r), c);
      double t = 0.0;
      const std::optional<Eigen::Vector3d> p = cast_ray(o, panel, holes, g, g.R_panel_sls * dir_sls, t);
      if (!p) continue;
      bool dropped = false;
      for (const auto& dr : drops)
        if (std::hypot(p->x() - dr.x(), p->y() - dr.y()) < dr.z()) dropped = true;
      if (dropped) continue;
      double range = t + o.noise * gauss(rr);
      if (o.outlier_fraction > 0 && u01(rr) < o.outlier_fraction)
        range += (u01(rr) < 0.5 ? -1.0 : 1.0) * (0.002 + 0.018 * u01(rr));
      grid[static_cast<std::size_t>(r) * g.cols + c] = (range * dir_sls).cast<float>();
      valid[static_cast<std::size_t>(r) * g.cols + c] = 1;
    }
  }
}

// The valid grid points as vertices, and two triangles per grid cell, none across a
// depth jump (an edge longer than six spacings).
void mesh_grid(const std::vector<Eigen::Vector3f>& grid, const std::vector<std::uint8_t>& valid,
               std::size_t rows, std::size_t cols, double spacing, SynthScan& scan) {
  constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> index(rows * cols, kNone);
  for (std::size_t k = 0; k < rows * cols; ++k)
    if (valid[k]) {
      index[k] = static_cast<std::uint32_t>(scan.vertices.size());
      scan.vertices.push_back(grid[k]);
    }
  const float max_edge = static_cast<float>(6.0 * spacing);
  auto ok = [&](std::uint32_t a, std::uint32_t b) {
    return (scan.vertices[a] - scan.vertices[b]).norm() <= max_edge;
  };
  for (std::size_t r = 0; r + 1 < rows; ++r)
    for (std::size_t c = 0; c + 1 < cols; ++c) {
      const std::uint32_t a = index[r * cols + c], b = index[r * cols + c + 1],
                          cc = index[(r + 1) * cols + c], dd = index[(r + 1) * cols + c + 1];
      if (a != kNone && b != kNone && dd != kNone && ok(a, b) && ok(b, dd) && ok(a, dd))
        scan.triangles.push_back({a, dd, b});
      if (a != kNone && cc != kNone && dd != kNone && ok(a, cc) && ok(cc, dd) && ok(a, dd))
        scan.triangles.push_back({a, cc, dd});
    }
  for (const auto& t : scan.triangles)
    scan.panel_area += 0.5 * static_cast<double>((scan.vertices[t[1]] - scan.vertices[t[0]])
                                                     .cross(scan.vertices[t[2]] - scan.vertices[t[0]])
                                                     .norm());
}

// Vertices and triangles in random order (as some scanner software writes them).
void shuffle_mesh(SynthScan& scan, std::mt19937_64& rng) {
  std::vector<std::uint32_t> perm(scan.vertices.size());
  std::iota(perm.begin(), perm.end(), 0u);
  std::shuffle(perm.begin(), perm.end(), rng);
  std::vector<Eigen::Vector3f> v(scan.vertices.size());
  for (std::size_t i = 0; i < perm.size(); ++i) v[perm[i]] = scan.vertices[i];
  scan.vertices.swap(v);
  for (auto& t : scan.triangles)
    for (auto& i : t) i = perm[i];
  std::shuffle(scan.triangles.begin(), scan.triangles.end(), rng);
}

// The planted dents, bumps and holes in 'sls'.
std::vector<TruthDefect> truth_defects(const DoorPanel& panel, const std::vector<Eigen::Vector3d>& holes,
                                       const Eigen::Isometry3d& T_sls_panel) {
  std::vector<TruthDefect> out;
  for (const PlantedDefect& d : panel.defects()) {
    TruthDefect t;
    t.defect_class = d.height < 0 ? "dent" : "bump";
    t.position =
        T_sls_panel * Eigen::Vector3d(d.centre.x(), d.centre.y(), panel.z(d.centre.x(), d.centre.y()));
    const Eigen::Vector3d n_panel = panel.normal(d.centre.x(), d.centre.y());
    t.normal = T_sls_panel.linear() * n_panel;
    t.diameter = d.diameter;
    // The defect is planted along the panel's z; its depth is measured along the
    // surface normal (as a gauge held normal to the panel reads it).
    t.height = d.height * n_panel.z();
    t.beside = d.beside;
    t.gap = d.gap;
    out.push_back(t);
  }
  for (const Eigen::Vector3d& h : holes) {
    TruthDefect t;
    t.defect_class = "hole";
    t.position = T_sls_panel * Eigen::Vector3d(h.x(), h.y(), panel.z_nominal(h.x(), h.y()));
    t.normal = T_sls_panel.linear() * panel.normal(h.x(), h.y());
    t.diameter = h.z();
    t.height = 0.0;
    out.push_back(t);
  }
  return out;
}

// The design features (handle, crease, border, window) as points every 10 mm in 'sls'.
std::vector<TruthFeature> truth_features(const PanelShape& shape, const DoorPanel& panel,
                                         const Eigen::Isometry3d& T_sls_panel) {
  const double W = shape.width, H = shape.height;
  std::vector<TruthFeature> out;
  auto feature_line = [&](const std::string& name, double radius, auto&& at, double len) {
    TruthFeature f;
    f.name = name;
    f.radius = radius;
    for (double s = 0.0; s <= len; s += 0.01) {
      const Eigen::Vector2d q = at(s);
      if (q.x() < 0 || q.x() > W || q.y() < 0 || q.y() > H) continue;
      f.points.push_back(T_sls_panel * Eigen::Vector3d(q.x(), q.y(), panel.z_nominal(q.x(), q.y())));
    }
    out.push_back(std::move(f));
  };
  if (shape.handle) {
    const Eigen::Vector2d hc = panel.handle_centre();
    feature_line(
        "handle", 0.03, [&](double s) { return Eigen::Vector2d(hc.x() - 0.05 + s, hc.y()); }, 0.1);
  }
  for (std::size_t k = 0; k < shape.lines.size(); ++k) {
    const CharacterLine& l = shape.lines[k];
    const Eigen::Vector2d dir(std::cos(l.angle), std::sin(l.angle));
    const double len = 2.0 * std::hypot(W, H);
    feature_line(
        "line" + std::to_string(k), 0.5 * l.width + 0.01,
        [&](double s) -> Eigen::Vector2d { return l.point + (s - 0.5 * len) * dir; }, len);
  }
  if (shape.crease)
    feature_line(
        "crease", 0.02, [&](double s) { return Eigen::Vector2d(s, panel.crease_y(s)); }, W);
  feature_line(
      "border", 0.02,
      [&](double s) {
        const double per = 2 * (W + H);
        s = std::fmod(s, per);
        if (s < W) return Eigen::Vector2d(s, 0.0);
        if (s < W + H) return Eigen::Vector2d(W, s - W);
        if (s < 2 * W + H) return Eigen::Vector2d(2 * W + H - s, H);
        return Eigen::Vector2d(0.0, per - s);
      },
      2 * (W + H));
  if (shape.window) {
    const double x0 = 0.1 * W, x1 = 0.9 * W, y0 = 0.68 * H, y1 = 0.93 * H, w = x1 - x0, h = y1 - y0;
    feature_line(
        "window", 0.02,
        [&](double s) {
          if (s < w) return Eigen::Vector2d(x0 + s, y0);
          if (s < w + h) return Eigen::Vector2d(x1, y0 + s - w);
          if (s < 2 * w + h) return Eigen::Vector2d(x1 - (s - w - h), y1);
          return Eigen::Vector2d(x0, y1 - (s - 2 * w - h));
        },
        2 * (w + h));
  }
  return out;
}

}  // namespace

SynthScan synthesize_scan(const ScanOptions& o) {
  check_options(o);
  // One generator for the whole panel, drawn from in this order: defects, holes, the
  // sensor's tilt, the dropouts, the shuffle (the range noise has per-row seeds).
  std::mt19937_64 rng(splitmix(o.seed));
  const DoorPanel probe(o.shape, {});
  const DoorPanel panel(o.shape, place_near_features(o, probe, place_defects(o, probe, rng), rng));
  const std::vector<Eigen::Vector3d> holes = place_holes(o, panel, rng);
  const SensorGrid sensor = place_sensor(o, panel, rng);
  std::vector<Eigen::Vector3d> drops;  // discs of missing data: x, y, r
  for (int k = 0; k < o.dropouts; ++k) {
    std::uniform_real_distribution<double> ux(0.0, o.shape.width), uy(0.0, o.shape.height), ur(0.002, 0.006);
    drops.emplace_back(ux(rng), uy(rng), ur(rng));
  }

  std::vector<Eigen::Vector3f> grid;
  std::vector<std::uint8_t> valid;
  sample_range_grid(o, panel, holes, drops, sensor, grid, valid);
  SynthScan scan;
  scan.T_sls_panel = sensor.T_sls_panel;
  mesh_grid(grid, valid, sensor.rows, sensor.cols, o.spacing, scan);
  if (o.shuffle) shuffle_mesh(scan, rng);
  if (o.tilt && o.tilt->z() != 0.0) {
    // A sensor rolled about its axis sees the same grid, turned in its frame.
    const Eigen::Matrix3f R =
        Eigen::AngleAxisf(static_cast<float>(o.tilt->z()), Eigen::Vector3f::UnitZ()).matrix();
    for (Eigen::Vector3f& v : scan.vertices) v = R * v;
    scan.T_sls_panel.prerotate(Eigen::AngleAxisd(o.tilt->z(), Eigen::Vector3d::UnitZ()));
  }
  scan.defects = truth_defects(panel, holes, scan.T_sls_panel);
  scan.features = truth_features(o.shape, panel, scan.T_sls_panel);
  return scan;
}

}  // namespace dentmark::sim::scan
