#include "dentmark/host/detect/height_map.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>

#include "background.h"
#include "stray_points.h"
#include "threads.h"

namespace dentmark::detect {
namespace {

// A leaf whose surface the sensor saw: the area-weighted cosine between its triangles'
// normals and the ray to the sensor, |S . ray| / A, is at least this (84 degrees off the
// ray; no scanner measures a surface more nearly edge-on).
constexpr float kFacingSensor = 0.1f;

// A panel that falls away from its plane by this much (m) over its mean radius is clearly
// convex on one side (a door of 3 m radius, 1 m across: ~30 mm; a flat roof's middle
// at 10 m: ~10 mm).
constexpr double kClearBulge = 2e-3;

// A body panel bulges outwards: a door, hood, roof or fender is convex on the side that
// faces the world. How far the surface falls away from its plane's normal w over the
// leaves `use` selects (m; positive when it bulges towards +w): h = (x - c) . w fitted
// as a + b r² over the leaves, r their distance from c across w, read at the leaves'
// mean r². A flat or saddle-shaped panel gives about 0.
template <class Use>
double bulge_towards(const OctreeLeaves& leaves, Use use, const Eigen::Vector3d& c, const Eigen::Vector3d& w,
                     double max_leaf_area) {
  constexpr std::int64_t kChunks = 64;  // fixed chunks summed in order: the same bits on any threads
  struct Sums {
    double a = 0.0, h = 0.0, r2 = 0.0, hr2 = 0.0, r4 = 0.0;
  };
  std::vector<Sums> chunk(kChunks);
  const auto count = static_cast<std::int64_t>(leaves.size());
#pragma omp parallel for schedule(static)
  for (std::int64_t ch = 0; ch < kChunks; ++ch) {
    Sums& cs = chunk[static_cast<std::size_t>(ch)];
    for (std::int64_t i = count * ch / kChunks; i < count * (ch + 1) / kChunks; ++i) {
      if (!use(static_cast<std::size_t>(i))) continue;
      const OctreeLeaf& l = leaves[static_cast<std::size_t>(i)];
      const double a = std::min(static_cast<double>(l.area), max_leaf_area);
      const Eigen::Vector3d d = l.centroid.cast<double>() - c;
      const double h = d.dot(w), r2 = d.squaredNorm() - h * h;
      cs.a += a, cs.h += a * h, cs.r2 += a * r2, cs.hr2 += a * h * r2, cs.r4 += a * r2 * r2;
    }
  }
  Sums all;
  for (const Sums& cs : chunk)
    all.a += cs.a, all.h += cs.h, all.r2 += cs.r2, all.hr2 += cs.hr2, all.r4 += cs.r4;
  if (!(all.a > 0.0)) return 0.0;
  const double mean_r2 = all.r2 / all.a;
  const double var_r2 = all.r4 / all.a - mean_r2 * mean_r2;
  if (!(var_r2 > 0.0)) return 0.0;
  const double slope = (all.hr2 / all.a - all.h / all.a * mean_r2) / var_r2;  // dh / d(r²)
  return -slope * mean_r2;
}

// Where the surface runs steeply through the octree's grid (a chart's side at 45 degrees
// to it), the leaves' centroids fall in steps, and a pixel between two surface pixels
// can get none: on a curved side whole columns of such pixels, which read as a cut
// through the panel (its border). (A single view's map lies nearly square to the grid,
// the scan frame's: there filling its few such pixels changed 1 finding in 240, for the
// worse, on our doors.) A pixel left empty between two surface pixels within
// layer_depth of each other, along its row or its column, takes their mean; one the
// sensor saw through (a leaf behind it) stays empty.
void fill_aliasing_gaps(HeightMap& map, float layer) {
  std::vector<std::uint8_t> seen_through(map.size(), 0);
  for (const Eigen::Vector3f& b : map.behind)
    if (const long k = map.pixel_of(b.x(), b.y()); k >= 0) seen_through[static_cast<std::size_t>(k)] = 1;
  const std::vector<float> weight = map.weight;  // before any fill: gaps one pixel wide only
  const auto fill = [&](std::size_t k, std::size_t a, std::size_t b) {
    if (!(weight[a] > 0.0f && weight[b] > 0.0f) || std::abs(map.w[a] - map.w[b]) > layer) return false;
    map.u[k] = 0.5f * (map.u[a] + map.u[b]), map.v[k] = 0.5f * (map.v[a] + map.v[b]);
    map.w[k] = 0.5f * (map.w[a] + map.w[b]);
    map.weight[k] = 0.5f * (weight[a] + weight[b]);
    map.cos_tilt[k] = 0.5f * (map.cos_tilt[a] + map.cos_tilt[b]);
    return true;
  };
  const auto cols = static_cast<std::size_t>(map.cols);
#pragma omp parallel for schedule(static)
  for (int r = 1; r < map.rows - 1; ++r)
    for (std::size_t c = 1; c + 1 < cols; ++c) {
      const std::size_t k = static_cast<std::size_t>(r) * cols + c;
      if (weight[k] > 0.0f || seen_through[k]) continue;
      if (!fill(k, k - 1, k + 1)) fill(k, k - cols, k + cols);
    }
}

// --- The stages of build_height_map ---

// The panel's box: per axis the middle 98 % of the leaves (sampled), widened by a
// quarter of its largest side each way, holds every leaf of a real scan. A stray leaf
// beyond it (an outlier tens or hundreds of metres off, meshed to the panel) stays out of
// the plane, whose scatter it would dominate by its distance, and off the map, which it
// would stretch to gigapixels.
Box panel_box(const OctreeLeaves& leaves) {
  const std::size_t stride = std::max<std::size_t>(1, leaves.size() / 100000);
  std::vector<float> x[3];
  for (std::size_t i = 0; i < leaves.size(); i += stride)
    if (leaves[i].area > 0.0f)
      for (int a = 0; a < 3; ++a) x[a].push_back(leaves[i].centroid[a]);
  return middle_box(x);
}

// The map's plane through the leaves `use` selects: its frame in map.origin and map.axes,
// w towards the sensor (or, on a chart, to chart_w's side; without a sensor, the side the
// panel bulges to). The plane runs through the area-weighted leaf centroids (weighted
// scatter of leaf means): one pass of sums about a point near the data, in fixed chunks
// summed in order, so the same plane to the last bit whatever the number of threads.
// A leaf counts at most max_leaf_area.
template <class Use>
void fit_map_plane(const OctreeLeaves& leaves, Use use, double max_leaf_area, const Eigen::Vector3d& chart_w,
                   HeightMap& map) {
  struct Sums {
    double area = 0.0;
    Eigen::Vector3d p = Eigen::Vector3d::Zero(), s = Eigen::Vector3d::Zero();
    Eigen::Matrix3d pp = Eigen::Matrix3d::Zero();
  };
  constexpr std::int64_t kChunks = 64;
  const bool chart = chart_w.squaredNorm() > 0.0;
  Eigen::Vector3d x0 = Eigen::Vector3d::Zero();
  if (!leaves.empty()) x0 = leaves[leaves.size() / 2].centroid.cast<double>();
  const auto leaf_count = static_cast<std::int64_t>(leaves.size());
  std::vector<Sums> chunk(kChunks);
#pragma omp parallel for schedule(static)
  for (std::int64_t ch = 0; ch < kChunks; ++ch) {
    Sums& cs = chunk[static_cast<std::size_t>(ch)];
    for (std::int64_t i = leaf_count * ch / kChunks; i < leaf_count * (ch + 1) / kChunks; ++i) {
      const OctreeLeaf& l = leaves[static_cast<std::size_t>(i)];
      cs.s += l.sum_an.cast<double>();
      if (!use(static_cast<std::size_t>(i))) continue;
      // A leaf holds at most ~1.5 h² of surface (a plane cuts a cube in at most √2 h²);
      // more is a spike's triangles (an outlier vertex meshed to the panel, hundreds of
      // metres long), whose whole area lands in one leaf and would tilt the plane.
      const double a = std::min(static_cast<double>(l.area), max_leaf_area);
      const Eigen::Vector3d d = l.centroid.cast<double>() - x0, ad = a * d;
      cs.area += a, cs.p += ad;
      // (The upper triangle: the lower one is the same.)
      for (int r = 0; r < 3; ++r)
        for (int c = r; c < 3; ++c) cs.pp(r, c) += ad(r) * d(c);
    }
  }
  Sums all;
  for (const Sums& cs : chunk) all.area += cs.area, all.p += cs.p, all.s += cs.s, all.pp += cs.pp;
  const double A = all.area;
  const Eigen::Vector3d S = all.s;
  if (!(A > 0.0)) throw std::invalid_argument("scan has no surface area");
  const Eigen::Vector3d mean = all.p / A;  // relative to x0
  const Eigen::Vector3d c = x0 + mean;
  for (int i = 1; i < 3; ++i)
    for (int j = 0; j < i; ++j) all.pp(i, j) = all.pp(j, i);  // the lower triangle
  const Eigen::Matrix3d scatter = all.pp - A * mean * mean.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
  Eigen::Vector3d w = eig.eigenvectors().col(0).normalized();
  // The scatter's thinnest direction is the panel's normal when the scan is one
  // surface. With a wall far behind the panel in the scan as well, the gap between the
  // two can be the scatter's widest extent, and the plane turns edge-on to the panel.
  // The triangles' mean normal still faces the sensor: where the two disagree by more
  // than 45 degrees it is the map's normal.
  if (S.norm() > 0.1 * A && std::abs(w.dot(S.normalized())) < std::sqrt(0.5)) w = S.normalized();
  // Towards the sensor at the frame origin. An origin within 10 cm of the plane is no
  // sensor's (a profiler's or a part's frame): then towards the side the triangles face.
  const double side = w.dot(-c);
  if (std::abs(side) > 0.1 ? side < 0 : w.dot(S) < 0) w = -w;
  // An origin on the side the triangles face away from is a sensor's whose mesh is
  // wound the other way, or no sensor's at all (a vehicle's or a part's frame, its
  // origin inside the body): there the side the panel bulges to is its outside. (From
  // the inside every dent reads as a bump.)
  if (!chart && std::abs(side) > 0.1 && S.norm() > 0.1 * A && w.dot(S) < 0.0 &&
      bulge_towards(leaves, use, c, w, max_leaf_area) < -kClearBulge)
    w = -w;
  // A chart's map looks the way the whole scan's does: to chart_w's side. (Square along
  // the chart's axis instead of the fit's plane: 5 false alarms more over the other
  // generator's fenders, one dent's depth 0.27 mm better; the plane leaned 15-20 degrees
  // from the axis in both.)
  if (chart && w.dot(chart_w) < 0.0) w = -w;
  // u along the scatter's widest direction across w.
  // (Far off the panel's normal the wall's gap can be that direction: then the next.)
  Eigen::Vector3d u = eig.eigenvectors().col(2).normalized();
  u = u - u.dot(w) * w;
  if (u.norm() < 0.5) u = eig.eigenvectors().col(1) - eig.eigenvectors().col(1).dot(w) * w;
  u.normalize();
  const Eigen::Vector3d v = w.cross(u);
  map.origin = c;
  map.axes.row(0) = u.transpose();
  map.axes.row(1) = v.transpose();
  map.axes.row(2) = w.transpose();
}

// Leaf centroids in map coordinates (floats: 0.1 µm over 2 m), NaN for the leaves
// `on_map` leaves out, and the map's extent over them (one pixel of margin), in one
// pass. Throws when the map would pass 4e8 pixels.
template <class OnMap>
std::vector<Eigen::Vector3f> leaves_in_map(const OctreeLeaves& leaves, OnMap on_map, double pixel,
                                           HeightMap& map) {
  const auto count = static_cast<std::int64_t>(leaves.size());
  std::vector<Eigen::Vector3f> q(leaves.size());
  double umin = 1e18, umax = -1e18, vmin = 1e18, vmax = -1e18;
#pragma omp parallel for schedule(static) reduction(min : umin, vmin) reduction(max : umax, vmax)
  for (std::int64_t i = 0; i < count; ++i) {
    if (!on_map(static_cast<std::size_t>(i))) {
      q[i].setConstant(std::numeric_limits<float>::quiet_NaN());
      continue;
    }
    q[i] = map.to_map(leaves[i].centroid.cast<double>()).cast<float>();
    umin = std::min<double>(umin, q[i].x()), umax = std::max<double>(umax, q[i].x());
    vmin = std::min<double>(vmin, q[i].y()), vmax = std::max<double>(vmax, q[i].y());
  }
  map.u0 = umin - pixel, map.v0 = vmin - pixel;
  map.cols = static_cast<int>((umax - map.u0) / pixel) + 2;
  map.rows = static_cast<int>((vmax - map.v0) / pixel) + 2;
  if (static_cast<double>(map.cols) * map.rows > 4e8) throw std::invalid_argument("height map too large");
  return q;
}

// Each leaf's pixel (-1: none), and the map cut into bands of pixel rows with as many
// leaves each, one a thread (the map's empty window and borders would leave a thread
// idle otherwise): band b is pixels [band_first[b], band_first[b + 1]).
struct LeafPixels {
  std::unique_ptr<std::int32_t[]> pix;
  std::vector<std::int32_t> band_first;
  std::size_t bands = 0;
};

LeafPixels leaf_pixels(const HeightMap& map, const std::vector<Eigen::Vector3f>& q) {
  const auto count = static_cast<std::int64_t>(q.size());
  const std::size_t n = map.size();
  LeafPixels lp;
  // (Every entry is written here, by both threads: no serial fill first.)
  lp.pix.reset(new std::int32_t[q.size()]);
  std::int32_t* const pix = lp.pix.get();
  std::vector<std::int64_t> row_leaves(static_cast<std::size_t>(map.rows), 0);
  std::int64_t* per_row = row_leaves.data();
#pragma omp parallel for schedule(static) reduction(+ : per_row[:map.rows])
  for (std::int64_t i = 0; i < count; ++i) {
    int r = 0, c = 0;
    const bool on = map.cell_of(q[i].x(), q[i].y(), r, c);  // (NaN: off the map)
    pix[i] = on ? r * map.cols + c : -1;
    per_row[r] += on;
  }
  lp.bands = static_cast<std::size_t>(detail::thread_count());
  lp.band_first.assign(lp.bands + 1, static_cast<std::int32_t>(n));
  std::int64_t total = 0, seen = 0;
  for (const std::int64_t in_row : row_leaves) total += in_row;
  std::size_t b = 0;
  for (int r = 0; r < map.rows && b < lp.bands; ++r) {
    while (b < lp.bands && seen >= total * static_cast<std::int64_t>(b) / static_cast<std::int64_t>(lp.bands))
      lp.band_first[b++] = r * map.cols;
    seen += row_leaves[static_cast<std::size_t>(r)];
  }
  return lp;
}

// The map's pixels from the leaves on it: per pixel its tilt (cos_tilt), its
// area-weighted position (u, v, w) and weight (the leaves' area projected on the map
// plane per pixel area). A single view sees the front surface of each column; leaves
// more than layer_depth behind the column's front were seen through a hole (or are
// outliers) and go to map.behind when their surface faced the sensor. A band's pixels are
// summed by one thread, in leaf order: the same sums whatever the number of bands.
void fill_pixels(const OctreeLeaves& leaves, const std::vector<Eigen::Vector3f>& q, const LeafPixels& lp,
                 double pixel, double layer_depth, HeightMap& map) {
  const std::size_t n = map.size();
  const std::int32_t* const pix = lp.pix.get();
  const std::size_t bands = lp.bands;
  // The map's arrays, filled side by side (fresh memory: a page fault per 4 KB).
  std::vector<float> front;
  detail::side_by_side([&] { front.assign(n, -std::numeric_limits<float>::infinity()); },
                       [&] { map.u.assign(n, 0.0f); }, [&] { map.v.assign(n, 0.0f); },
                       [&] { map.w.assign(n, 0.0f); }, [&] { map.cos_tilt.assign(n, 1.0f); },
                       [&] { map.weight.assign(n, 0.0f); });
  // visit(band, leaf, pixel) for every leaf on the map, each band by one thread.
  const auto for_leaves_by_band = [&](auto&& visit) {
#pragma omp parallel for schedule(static, 1)
    for (std::size_t b = 0; b < bands; ++b) {
      const std::int32_t first = lp.band_first[b], last = lp.band_first[b + 1];
      for (std::size_t i = 0; i < leaves.size(); ++i) {
        // The pixels a band's leaves meet are scattered (Morton order is not the map's):
        // their arrays are fetched 24 leaves ahead (the passes 25-35 % faster).
        if (i + 24 < leaves.size()) {
          const std::int32_t kp = pix[i + 24];
          if (kp >= first && kp < last) {
            __builtin_prefetch(&front[kp]);
            __builtin_prefetch(&map.u[kp], 1);
            __builtin_prefetch(&map.v[kp], 1);
            __builtin_prefetch(&map.w[kp], 1);
          }
        }
        const std::int32_t k = pix[i];
        if (k >= first && k < last) visit(b, i, k);
      }
    }
  };
  // (Anchoring on the column's busiest leaf instead of its front lets a hole's backdrop
  // win the rim columns; an outlier in front only spoils its own pixel, which the median
  // removes.)
  for_leaves_by_band(
      [&](std::size_t, std::size_t i, std::int32_t k) { front[k] = std::max(front[k], q[i].z()); });
  const auto layer = static_cast<float>(layer_depth);
  const auto in_front = [&](std::size_t i, std::int32_t k) { return q[i].z() >= front[k] - layer; };
  std::vector<std::vector<Eigen::Vector3f>> behind(bands);
  // The tilt first: |S . w| / |S| per pixel, S = Σ a_i N_i of its leaves, summed in the
  // map's frame in the arrays that then take the positions (no fourth array of vectors).
  const Eigen::Matrix3f axes = map.axes.cast<float>();
  for_leaves_by_band([&](std::size_t, std::size_t i, std::int32_t k) {
    if (!in_front(i, k)) return;
    const Eigen::Vector3f s = axes * leaves[i].sum_an;
    map.u[k] += s.x(), map.v[k] += s.y(), map.w[k] += s.z();
  });
#pragma omp parallel for schedule(static)
  for (std::int64_t k = 0; k < static_cast<std::int64_t>(n); ++k) {
    const float nn = Eigen::Vector3f(map.u[k], map.v[k], map.w[k]).norm();
    if (nn > 0) map.cos_tilt[k] = std::abs(map.w[k]) / nn;
    map.u[k] = 0.0f, map.v[k] = 0.0f, map.w[k] = 0.0f;
  }
  // Area-weighted positions per pixel, straight into the map's arrays (a pixel holds one
  // or two leaves: float sums lose nothing), then divided in place. Leaves behind the
  // front are kept aside.
  const Eigen::Vector3f w_axis = axes.row(2).transpose();
  for_leaves_by_band([&](std::size_t band, std::size_t i, std::int32_t k) {
    if (!in_front(i, k)) {
      // Only surface the sensor faced: an outlier vertex behind the skin, meshed to its
      // neighbours, is a needle of triangles along its ray (a 20 mm spike: |S . ray| / A
      // ~0.01). Its leaves, traced back along their rays, all went through the one or two
      // pixels it left empty in the skin: a 1.6 mm "hole".
      const Eigen::Vector3f ray =
          map.has_viewpoint ? (map.viewpoint.cast<float>() - q[i]).normalized() : Eigen::Vector3f::UnitZ();
      if (std::abs(ray.dot(axes * leaves[i].sum_an)) >= kFacingSensor * leaves[i].area)
        behind[band].push_back(q[i]);
      return;
    }
    // The leaf's area projected on the map plane, |Σ a_i N_i . w|: a sample's footprint
    // on the map. A spike's triangles (an outlier vertex meshed to its neighbours) are
    // tens of times a normal one's area but cover no more of the map.
    const float a = std::abs(w_axis.dot(leaves[i].sum_an));
    map.weight[k] += a, map.u[k] += a * q[i].x(), map.v[k] += a * q[i].y(), map.w[k] += a * q[i].z();
  });
  for (const auto& b : behind) map.behind.insert(map.behind.end(), b.begin(), b.end());
  const auto inv_px2 = static_cast<float>(1.0 / (pixel * pixel));
#pragma omp parallel for schedule(static)
  for (std::int64_t k = 0; k < static_cast<std::int64_t>(n); ++k) {
    const float a = map.weight[k];
    if (!(a > 0.0f)) continue;  // no leaf: its tilt sums are 0 too, so cos_tilt is 1
    map.u[k] /= a, map.v[k] /= a, map.w[k] /= a;
    map.weight[k] = a * inv_px2;
  }
}

}  // namespace

HeightMap build_height_map(const LinearOctree& tree, double pixel, double layer_depth,
                           std::vector<std::uint8_t>* background_leaf, const Eigen::Vector3d& chart_w) {
  const auto& leaves = tree.leaves();
  HeightMap map;
  map.pixel = pixel;
  const Box box = panel_box(leaves);
  const auto in_box = [&](const OctreeLeaf& l) {
    return l.area > 0.0f && (l.centroid.array() >= box.lo.array()).all() &&
           (l.centroid.array() <= box.hi.array()).all();
  };
  const double max_leaf_area = 3.0 * tree.leaf_size() * tree.leaf_size();
  const auto in_panel_box = [&](std::size_t i) { return in_box(leaves[i]); };
  fit_map_plane(leaves, in_panel_box, max_leaf_area, chart_w, map);
  // A wall or the floor far behind the panel: its leaves leave the plane and the map.
  const Background background = find_background(tree, map, box);
  map.background_area = background.area;
  const auto on_map = [&](std::size_t i) {
    return in_panel_box(i) && (background.leaf.empty() || !background.leaf[i]);
  };
  if (!background.leaf.empty()) fit_map_plane(leaves, on_map, max_leaf_area, chart_w, map);
  map.viewpoint = map.to_map(Eigen::Vector3d::Zero());
  map.has_viewpoint = map.viewpoint.z() > 0.1;

  const std::vector<Eigen::Vector3f> q = leaves_in_map(leaves, on_map, pixel, map);
  fill_pixels(leaves, q, leaf_pixels(map, q), pixel, layer_depth, map);
  if (background_leaf) *background_leaf = background.leaf;
  if (chart_w.squaredNorm() > 0.0) fill_aliasing_gaps(map, static_cast<float>(layer_depth));
  return map;
}

}  // namespace dentmark::detect
