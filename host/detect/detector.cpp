#include "dentmark/host/detect/detector.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <numbers>
#include <numeric>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "box_mean.h"
#include "components.h"
#include "dentmark/common/geometry/plane_fit.h"
#include "dentmark/host/detect/apex_fit.h"
#include "dentmark/host/detect/grouping.h"
#include "dentmark/host/detect/linear_octree.h"
#include "dentmark/host/detect/reference_surface.h"
#include "dentmark/host/ingest/units.h"
#include "holes.h"
#include "median.h"
#include "threads.h"

namespace dentmark::detect {
namespace {

using Clock = std::chrono::steady_clock;

// A candidate whose surroundings deviate from their own quadratic by more than this many
// times the map's deviation noise is not on a smooth panel: it cannot be measured as a
// dent there, and is taken as part of the design around it.
constexpr double kRoughRing = 3.5;

// Robust sigma (1.4826 MAD) of the finite, selected values, sampled.
double robust_sigma(const cv::Mat& values, const cv::Mat& select) {
  // 60 k samples: the MAD to ~0.5 %, at a fifth of the cost of 300 k. Gathered in two
  // halves side by side (the strided reads touch every cache line of both images), kept
  // in order: the same sample whatever the thread count.
  const std::size_t total = values.total(), stride = std::max<std::size_t>(1, total / 60000);
  const std::size_t picks = (total + stride - 1) / stride;
  const float* v = values.ptr<float>();
  const std::uint8_t* m = select.ptr<std::uint8_t>();
  std::vector<double> half[2];
#pragma omp parallel for schedule(static) num_threads(std::min(2, detail::thread_count()))
  for (int part = 0; part < 2; ++part)
    for (std::size_t j = picks * part / 2; j < picks * (part + 1) / 2; ++j) {
      const std::size_t i = j * stride;
      if (m[i] && std::isfinite(v[i])) half[part].push_back(v[i]);
    }
  std::vector<double> s = std::move(half[0]);
  s.insert(s.end(), half[1].begin(), half[1].end());
  if (s.size() < 10) return 0.0;
  const double med = median_of(s);
  for (auto& x : s) x = std::abs(x - med);
  return 1.4826 * median_of(std::move(s));
}

struct Component {
  std::vector<std::int32_t> pixels;
  bool has_deviation = false;  // found by the deviation test, not only by eq. (3)
};

}  // namespace

Detection detect(const ingest::MeshView& mesh, const DetectConfig& cfg) {
  Detection out;
  auto t0 = Clock::now();
  auto lap = [&](const char* stage) {
    const auto now = Clock::now();
    out.timing.emplace_back(stage, std::chrono::duration<double>(now - t0).count());
    t0 = now;
  };
  DetectionStats& st = out.stats;
  st.vertices = mesh.vertex_count();
  st.triangles = mesh.triangle_count();
  st.spacing = ingest::point_spacing(mesh);
  const double h = std::max(cfg.finest_node_size, 2.0 * st.spacing);
  st.leaf_size = h;

  // --- Linear octree, eq. (1)-(3) ---
  // Released once the map is built: later stages reuse its memory.
  auto tree_ptr = std::make_unique<const LinearOctree>(LinearOctree::build(mesh, h));
  const LinearOctree& tree = *tree_ptr;
  st.depth = tree.depth();
  st.leaves = tree.leaves().size();
  for (const auto& l : tree.leaves()) st.surface_area += l.area;
  lap("octree");
  {
    // Every stride-th leaf with 4 triangles or more (NaN marks the others).
    const std::size_t stride = std::max<std::size_t>(1, tree.leaves().size() / 100000);
    std::vector<double> sig((tree.leaves().size() + stride - 1) / stride);
#pragma omp parallel for schedule(static)
    for (std::size_t j = 0; j < sig.size(); ++j)
      sig[j] = tree.leaves()[j * stride].count >= 4 ? tree.stats(j * stride, j * stride + 1).sigma
                                                    : std::numeric_limits<double>::quiet_NaN();
    std::erase_if(sig, [](double x) { return std::isnan(x); });
    st.noise_floor_sigma = median_of(std::move(sig));
  }
  // Thresholds adapt to the measured noise floor of the normals.
  const double leaf_sigma = std::hypot(st.noise_floor_sigma, cfg.feature_angle);
  // Coarse nodes dilute a small feature's spread by its share of the node's area, so
  // they are split at half the leaf threshold (the paper's single threshold misses
  // 1 cm features in 10 cm nodes on dense, noisy scans).
  const std::vector<std::uint32_t> feature = tree.feature_leaves(0.5 * leaf_sigma, leaf_sigma);
  const auto groups = group_features(tree, feature, cfg.min_occupancy);
  st.feature_leaves = feature.size();
  st.feature_groups = groups.size();
  lap("features");

  // --- Height map and robust reference surface ---
  out.map = build_height_map(tree, h, cfg.hole_depth);
  lap("map");
  const HeightMap& map = out.map;
  const int rows = map.rows, cols = map.cols;
  // The feature groups' pixels (eq. 3-4 candidates); the leaves are not needed after this.
  std::vector<long> group_pixels;
  for (const auto& g : groups)
    for (auto l : g) {
      const Eigen::Vector3d q = map.to_map(tree.leaves()[l].centroid.cast<double>());
      if (const long k = map.pixel_of(q.x(), q.y()); k >= 0) group_pixels.push_back(k);
    }
  // Working memory: the octree's leaves and the records of its build; the map's arrays and
  // deviation images; the map's build (per leaf: pixel; per pixel: front).
  st.working_bytes =
      tree.bytes() + map.size() * (6 * 4 + 4 * 4 + 8) + tree.leaves().size() * 4 + map.size() * 4;
  tree_ptr.reset();
  cv::Mat weight(rows, cols, CV_32F, const_cast<float*>(map.weight.data()));
  cv::Mat occupied = weight > 0.0f;
  // Outside: empty regions larger than a (10 mm)² dropout or touching the map border.
  cv::Mat edge_zone;
  {
    const Components empty = label_components(weight <= 0.0f, 4);
    const double big = std::pow(0.01 / h, 2);
    std::vector<std::uint8_t> outside(static_cast<std::size_t>(empty.count), 0);
    for (std::size_t i = 1; i < outside.size(); ++i)
      outside[i] = empty.area[i] >= big || empty.touches_border[i];
    cv::Mat out_mask(rows, cols, CV_8U);
    const int* lp = empty.labels.ptr<int>();  // 0 on occupied pixels, which outside[0] = 0 leaves out
    std::uint8_t* op = out_mask.ptr<std::uint8_t>();
#pragma omp parallel for schedule(static)
    for (std::int64_t k = 0; k < static_cast<std::int64_t>(map.size()); ++k)
      op[k] = outside[static_cast<std::size_t>(lp[k])] ? 255 : 0;
    const int rad = std::max(2, static_cast<int>(std::lround(0.003 / h)));
    cv::dilate(out_mask, edge_zone, cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * rad + 1, 2 * rad + 1}));
    edge_zone &= occupied;
  }
  cv::Mat interior = occupied & ~edge_zone;

  // Detection scales (box sides) in metres: dents of 5 mm and up.
  std::vector<int> scales;
  for (double s : {0.003, 0.007, 0.015}) {
    int k = std::max(1, static_cast<int>(std::lround(s / h)));
    if (k % 2 == 0) ++k;
    if (std::find(scales.begin(), scales.end(), k) == scales.end()) scales.push_back(k);
  }
  std::vector<float> ref_weights(map.weight);
  ReferenceSurface reference(map, cfg.reference_window);
  const std::vector<float>* fitted = nullptr;
  cv::Mat dev(rows, cols, CV_32F), cand;
  // Working images, reused by every iteration.
  cv::Mat dz(rows, cols, CV_32F), wv(rows, cols, CV_32F), dm, num, valid(rows, cols, CV_8U);
  // Pixels far from their 3 x 3 median: outlier spikes.
  cv::Mat spike(rows, cols, CV_8U);
  // Pixels found not to be skin in any fit so far: spikes, and pixels more than hole_depth
  // off it (a hole's backdrop, a handle's top). They stay out of every later fit: left
  // to the candidates, which change from one fit to the next, they come back into every
  // other fit and pull it by their weight times their distance (a 10 mm spike moves a
  // whole window's reference by ~0.1 mm).
  cv::Mat off_skin(rows, cols, CV_8U, cv::Scalar(0)), grown;
  std::vector<double> scale_sigma(scales.size(), 0.0);
  const int iterations = std::max(1, cfg.reference_iterations);
  for (int it = 0; it < iterations; ++it) {
    fitted = &reference.fit(ref_weights);  // after the first: only where candidates changed
    const std::vector<float>& ref = *fitted;
    // Deviation from the reference along the normal; where it is valid, also the
    // deviation and weight that the box filters average (0 elsewhere).
    float *d = dev.ptr<float>(), *dzp = dz.ptr<float>(), *wvp = wv.ptr<float>();
    std::uint8_t* vp = valid.ptr<std::uint8_t>();
#pragma omp parallel for schedule(static)
    for (std::int64_t k = 0; k < static_cast<std::int64_t>(map.size()); ++k) {
      const bool ok = map.weight[k] > 0.0f && std::isfinite(ref[k]);
      d[k] = ok ? (map.w[k] - ref[k]) * map.cos_tilt[k] : std::numeric_limits<float>::quiet_NaN();
      dzp[k] = ok ? d[k] : 0.0f;
      wvp[k] = ok ? map.weight[k] : 0.0f;
      vp[k] = ok ? 255 : 0;
    }
    st.deviation_noise = robust_sigma(dev, interior);
    // Median first: a lone outlier spike cannot survive it; a defect of a few pixels can.
    if (scales.front() >= 3)
      cv::medianBlur(dz, dm, 3);
    else
      dz.copyTo(dm);
    float* wdm = dz.ptr<float>();  // the weighted median deviation, in dz's place
    const float* dmp = dm.ptr<float>();
    std::uint8_t *sp = spike.ptr<std::uint8_t>(), *osk = off_skin.ptr<std::uint8_t>();
    const auto spike_height =
        static_cast<float>(std::max(cfg.detection_sigma * st.deviation_noise, 0.5 * cfg.min_height));
    const auto far_off = static_cast<float>(cfg.hole_depth);
#pragma omp parallel for schedule(static)
    for (std::int64_t k = 0; k < static_cast<std::int64_t>(map.size()); ++k) {
      // A spike stands out of its neighbourhood by more than the neighbourhood stands out
      // of the reference; a narrow defect's apex (its neighbours deep too) does not.
      const float off = std::abs(dzp[k] - dmp[k]);
      sp[k] = vp[k] && off > spike_height && off > 2.0f * std::abs(dmp[k]) ? 255 : 0;
      osk[k] |= sp[k] | (std::abs(d[k]) > far_off ? 255 : 0);  // NaN compares false
      wdm[k] = wvp[k] * dmp[k];
    }
    cand.create(rows, cols, CV_8U);
    cand.setTo(0);
    std::uint8_t* cp = cand.ptr<std::uint8_t>();
    for (std::size_t s = 0; s < scales.size(); ++s) {
      const int k = scales[s];
      // The windowed mean where the window is at least 30 % full, NaN elsewhere.
      box_mean(dz, wv, k, 0.3f * static_cast<float>(k * k), num);
      const float* rs = num.ptr<float>();
      scale_sigma[s] = robust_sigma(num, interior);
      const float thr =
          static_cast<float>(std::max(cfg.detection_sigma * scale_sigma[s], 0.5 * cfg.min_height));
#pragma omp parallel for schedule(static)
      for (std::int64_t q = 0; q < static_cast<std::int64_t>(map.size()); ++q)
        cp[q] |= (vp[q] && std::abs(rs[q]) > thr) ? 255 : 0;
    }
    if (it + 1 < iterations) {
      cand |= off_skin;  // (this iteration's candidates are not needed after this)
      cv::dilate(cand, grown, cv::getStructuringElement(cv::MORPH_RECT, {5, 5}));
      const std::uint8_t* g = grown.ptr<std::uint8_t>();
#pragma omp parallel for schedule(static)
      for (std::int64_t k = 0; k < static_cast<std::int64_t>(map.size()); ++k)
        ref_weights[k] = g[k] ? 0.0f : map.weight[k];
    }
  }
  lap("reference");
  const std::vector<float>& ref = *fitted;

  // --- Holes: enclosed regions seen through; their rim is theirs, not a dent's ---
  const std::vector<HoleRegion> holes = find_holes(map, dev, ref, cfg.hole_depth, cfg.max_hole_diameter);
  cv::Mat hole_zone(rows, cols, CV_8U, cv::Scalar(0));
  for (const auto& hr : holes) {
    for (auto k : hr.pixels) hole_zone.data[k] = 255;
    for (auto k : hr.seen_deep) hole_zone.data[k] = 255;
  }
  {
    const int rad = std::max(2, static_cast<int>(std::lround(0.002 / h)));
    cv::dilate(hole_zone, hole_zone,
               cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * rad + 1, 2 * rad + 1}));
  }
  cand &= ~hole_zone;

  // --- Candidates: deviation test or eq. (3)-(4) feature groups ---
  cv::Mat octree_px(rows, cols, CV_8U, cv::Scalar(0));
  for (const long k : group_pixels) octree_px.data[k] = 255;
  octree_px &= ~hole_zone;
  cv::Mat any = cand | octree_px;
  const cv::Mat not_surface = any | spike;  // left out of the normals' plane fits
  cv::Mat labels;
  const int ncomp = cv::connectedComponents(any, labels, 8, CV_32S);
  std::vector<Component> comps(static_cast<std::size_t>(std::max(ncomp, 1)));
  {
    const int* lab = labels.ptr<int>();
    for (std::int32_t k = 0; k < rows * cols; ++k)
      if (lab[k] > 0) {
        comps[static_cast<std::size_t>(lab[k])].pixels.push_back(k);
        if (cand.data[k]) comps[static_cast<std::size_t>(lab[k])].has_deviation = true;
      }
  }
  out.labels.assign(map.size(), -1);
  out.deviation.assign(dev.ptr<float>(), dev.ptr<float>() + map.size());
  const double sigma3 = std::max(scale_sigma.front(), 1e-9);
  const Eigen::Vector3d w_axis = map.axes.row(2).transpose();

  auto point_of = [&](std::int32_t k) { return Eigen::Vector3d(map.u[k], map.v[k], map.w[k]); };
  // Least-squares plane (common/geometry) over a normal_patch square around pixel (pr, pc),
  // pixels set in 'exclude' left out; oriented towards the sensor.
  auto patch_normal = [&](int pr, int pc, const cv::Mat& exclude) -> Eigen::Vector3d {
    std::vector<Eigen::Vector3d> pts;
    std::vector<double> wts;
    const int hp = std::max(1, static_cast<int>(std::lround(0.5 * cfg.normal_patch / h)));
    for (int r = std::max(0, pr - hp); r <= std::min(rows - 1, pr + hp); ++r)
      for (int c = std::max(0, pc - hp); c <= std::min(cols - 1, pc + hp); ++c) {
        const int k = r * cols + c;
        if (!(map.weight[k] > 0.0f) || exclude.data[k]) continue;
        pts.push_back(map.to_scan(map.u[k], map.v[k], map.w[k]));
        wts.push_back(map.weight[k]);
      }
    try {
      if (pts.size() >= 3) return fit_plane(pts, wts, w_axis).normal;
    } catch (const std::exception&) {
    }
    return w_axis;
  };

  struct Shape {
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    double length = 0.0, width = 0.0, area = 0.0;
    bool touches_edge = false;
  };
  // Shape: principal axes of the pixel cloud.
  auto shape_of = [&](const Component& comp) {
    Shape sh;
    for (auto k : comp.pixels) sh.mean += Eigen::Vector2d(k % cols, k / cols);
    sh.mean /= static_cast<double>(comp.pixels.size());
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (auto k : comp.pixels) {
      const Eigen::Vector2d d = Eigen::Vector2d(k % cols, k / cols) - sh.mean;
      cov += d * d.transpose();
      sh.touches_edge = sh.touches_edge || edge_zone.data[k];
      sh.area += map.weight[k] * h * h;
    }
    cov /= static_cast<double>(comp.pixels.size());
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
    sh.length = (4.0 * std::sqrt(std::max(0.0, eig.eigenvalues()(1))) + 1.0) * h;
    sh.width = (4.0 * std::sqrt(std::max(0.0, eig.eigenvalues()(0))) + 1.0) * h;
    return sh;
  };
  auto design_reason_of = [&](const Shape& sh) -> const char* {
    if (sh.touches_edge) return "touches a border or opening";
    if (sh.length > cfg.max_defect_diameter) return "larger than any defect (handle, panel shape)";
    if (sh.length > 0.025 && sh.length / sh.width > cfg.max_elongation)
      return "long and thin (character line)";
    return nullptr;
  };
  // Pieces next to a design feature (the rim around a handle, the shoulders of a
  // crease) belong to it: a reference surface cannot follow them there.
  cv::Mat near_design(rows, cols, CV_8U, cv::Scalar(0));
  for (int ci = 1; ci < ncomp; ++ci) {
    const Component& comp = comps[static_cast<std::size_t>(ci)];
    if (comp.pixels.empty() || !design_reason_of(shape_of(comp))) continue;
    for (auto k : comp.pixels) near_design.data[k] = 255;
  }
  {
    const int rad = std::max(2, static_cast<int>(std::lround(0.008 / h)));
    cv::dilate(near_design, near_design,
               cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * rad + 1, 2 * rad + 1}));
  }
  // A piece of one: mostly within 8 mm of it, or peaking there (a handle's rim is
  // strongest at the handle). A defect whose edge merely reaches into the wide, shallow
  // band a crease leaves in the deviation keeps its own peak and stays a defect.
  auto next_to_design = [&](const Component& comp) {
    std::ptrdiff_t near = 0;
    std::int32_t peak = comp.pixels.front();
    float peak_dev = 0.0f;
    for (auto k : comp.pixels) {
      near += near_design.data[k] != 0;
      const float dv = std::abs(dev.at<float>(k / cols, k % cols));
      if (dv > peak_dev) peak_dev = dv, peak = k;
    }
    return near > 0 && (2 * near > static_cast<std::ptrdiff_t>(comp.pixels.size()) || near_design.data[peak]);
  };

  // The scan's own samples under the dent and bump candidates, for their apex depth.
  // Design features need none.
  const bool coarse = scales.front() < 3;
  const PixelSamples samples = [&] {
    std::vector<std::uint8_t> select(map.size(), 0);
    for (int ci = 1; ci < ncomp; ++ci) {
      const Component& comp = comps[static_cast<std::size_t>(ci)];
      if (comp.pixels.empty() || design_reason_of(shape_of(comp)) || next_to_design(comp)) continue;
      int c0 = cols, c1 = 0, r0 = rows, r1 = 0;
      for (auto k : comp.pixels)
        c0 = std::min(c0, k % cols), c1 = std::max(c1, k % cols), r0 = std::min(r0, k / cols),
        r1 = std::max(r1, k / cols);
      for (int r = std::max(0, r0 - 2); r <= std::min(rows - 1, r1 + 2); ++r)
        std::fill_n(select.begin() + r * cols + std::max(0, c0 - 2),
                    std::min(cols - 1, c1 + 2) - std::max(0, c0 - 2) + 1, 1);
    }
    return PixelSamples(mesh, map, select);
  }();
  lap("samples");

  for (int ci = 1; ci < ncomp; ++ci) {
    const Component& comp = comps[static_cast<std::size_t>(ci)];
    if (comp.pixels.empty()) continue;
    const Shape shape = shape_of(comp);
    const Eigen::Vector2d mean = shape.mean;
    const double length = shape.length, area = shape.area;
    Finding f;
    f.pixels = static_cast<int>(comp.pixels.size());
    protocol::Defect& d = f.defect;
    d.area = area;
    d.normal = w_axis;
    const char* design_reason = design_reason_of(shape);
    if (!design_reason && next_to_design(comp)) design_reason = "next to a design feature";
    if (design_reason) {
      Eigen::Vector3d p = Eigen::Vector3d::Zero();
      double ws = 0.0, extreme = 0.0;
      for (auto k : comp.pixels) {
        p += map.weight[k] * point_of(k);
        ws += map.weight[k];
        const float dv = out.deviation[static_cast<std::size_t>(k)];
        if (std::isfinite(dv) && std::abs(dv) > std::abs(extreme)) extreme = dv;
      }
      d.defect_class = protocol::DefectClass::kDesignFeature;
      d.position = map.to_scan(p.x() / ws, p.y() / ws, p.z() / ws);
      d.diameter = length;
      d.height = extreme;
      d.score = 1.0;
      f.reason = design_reason;
      for (auto k : comp.pixels)
        out.labels[static_cast<std::size_t>(k)] = -2 - static_cast<int>(out.features.size());
      out.features.push_back(std::move(f));
      continue;
    }

    // --- Measure against a local reference fitted around the candidate ---
    int c0 = cols, c1 = 0, r0 = rows, r1 = 0;
    for (auto k : comp.pixels)
      c0 = std::min(c0, k % cols), c1 = std::max(c1, k % cols), r0 = std::min(r0, k / cols),
      r1 = std::max(r1, k / cols);
    const int margin = std::max(6, static_cast<int>(std::lround(std::max(length / h, 0.012 / h))));
    const int bc0 = std::max(0, c0 - margin), bc1 = std::min(cols - 1, c1 + margin),
              br0 = std::max(0, r0 - margin), br1 = std::min(rows - 1, r1 + margin);
    const double cu = mean.x() * h + map.u0, cv_ = mean.y() * h + map.v0;
    const double sc = 1.0 / (margin * h + 0.5 * length);
    Eigen::Matrix<double, 6, 6> N = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> rhs = Eigen::Matrix<double, 6, 1>::Zero();
    int ring = 0;
    double ring_ww = 0.0;  // Σ weight · w², for the ring's residual
    Eigen::Matrix<double, 6, 1> rhs_off = Eigen::Matrix<double, 6, 1>::Zero();
    double ring_off2 = 0.0;
    const int guard = std::max(2, static_cast<int>(std::lround(0.25 * length / h)));
    auto basis = [&](double pu, double pv) {
      const double x = (pu - cu) * sc, y = (pv - cv_) * sc;
      Eigen::Matrix<double, 6, 1> b;
      b << 1, x, y, x * x, x * y, y * y;
      return b;
    };
    for (int r = br0; r <= br1; ++r)
      for (int c = bc0; c <= bc1; ++c) {
        const int k = r * cols + c;
        if (!(map.weight[k] > 0.0f) || any.data[k] || edge_zone.data[k] || hole_zone.data[k] || spike.data[k])
          continue;
        // Keep the defect's faint rim out of its own reference.
        if (c >= c0 - guard && c <= c1 + guard && r >= r0 - guard && r <= r1 + guard) continue;
        // Residuals along the normal, as the deviation's: a pixel of a spike's steep
        // triangles is millimetres off in w but not along its normal.
        const double wk = map.weight[k] * static_cast<double>(map.cos_tilt[k]) * map.cos_tilt[k];
        const auto b = basis(map.u[k], map.v[k]);
        N += wk * b * b.transpose();
        rhs += wk * map.w[k] * b;
        ring_ww += wk * static_cast<double>(map.w[k]) * map.w[k];
        // The same ring's departure from the global reference (0 where it has none).
        const double off = std::isfinite(ref[static_cast<std::size_t>(k)])
                               ? map.w[k] - ref[static_cast<std::size_t>(k)]
                               : 0.0;
        rhs_off += wk * off * b;
        ring_off2 += wk * off * off;
        ++ring;
      }
    Eigen::Matrix<double, 6, 1> quad = Eigen::Matrix<double, 6, 1>::Zero(), quad_off = quad;
    bool local = false;
    if (ring >= 20) {
      const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(N);
      if (ldlt.info() == Eigen::Success && ldlt.vectorD().minCoeff() > 1e-8 * N(0, 0)) {
        quad = ldlt.solve(rhs);
        quad_off = ldlt.solve(rhs_off);
        local = quad.allFinite() && quad_off.allFinite();
      }
    }
    // The ring's rms residual about its quadratic, against the map's deviation noise:
    // about 0.7 around a defect on a smooth panel, up to 3 with another defect's tail in
    // it, 3.7-8 on the strip between two rolled edges that no quadratic follows (measured
    // at 0.5 mm, 40 µm noise). Where the panel curves too fast for a quadratic across
    // the ring (a fender's side) but the global reference follows it, the ring's
    // departure from that reference is smooth: the smaller of the two residuals counts.
    const auto rms_about = [&](const Eigen::Matrix<double, 6, 1>& q, const Eigen::Matrix<double, 6, 1>& r,
                               double zz) {
      return std::sqrt(std::max(0.0, (zz - 2.0 * q.dot(r) + q.dot(N * q)) / N(0, 0)));
    };
    const double rms_own = local ? rms_about(quad, rhs, ring_ww) : 0.0,
                 rms_off = local ? rms_about(quad_off, rhs_off, ring_off2) : 0.0;
    const double ring_rms = std::min(rms_own, rms_off);
    const bool rough_ring = ring_rms > kRoughRing * st.deviation_noise;
    // The local reference: the ring's own quadratic, or (where the global reference with a
    // quadratic correction describes the ring clearly better: a fender's side, where the
    // ring's own quadratic was 40 µm off under the apex) that.
    const bool on_global = local && rms_off < 0.8 * rms_own;
    const auto local_ref = [&](double pu, double pv, std::size_t k) -> double {
      if (!local) return ref[k];  // too little clean ring: the global reference
      return on_global ? reference.height_at(pu, pv) + basis(pu, pv).dot(quad_off) : basis(pu, pv).dot(quad);
    };
    const int bw = bc1 - bc0 + 1, bh = br1 - br0 + 1;
    std::vector<float> ldev(static_cast<std::size_t>(bw * bh), std::numeric_limits<float>::quiet_NaN());
    for (int r = br0; r <= br1; ++r)
      for (int c = bc0; c <= bc1; ++c) {
        const int k = r * cols + c;
        if (!(map.weight[k] > 0.0f) || spike.data[k]) continue;  // spikes: never the peak, never measured
        const double refw = local_ref(map.u[k], map.v[k], static_cast<std::size_t>(k));
        if (std::isfinite(refw))
          ldev[static_cast<std::size_t>((r - br0) * bw + (c - bc0))] =
              static_cast<float>((map.w[k] - refw) * map.cos_tilt[k]);
      }
    auto at = [&](int r, int c) { return ldev[static_cast<std::size_t>((r - br0) * bw + (c - bc0))]; };
    auto smooth = [&](int r, int c) {
      double s = 0.0, ws = 0.0;
      for (int dr = -1; dr <= 1; ++dr)
        for (int dc = -1; dc <= 1; ++dc) {
          const int rr = r + dr, cc = c + dc;
          if (rr < br0 || rr > br1 || cc < bc0 || cc > bc1) continue;
          const float v = at(rr, cc);
          if (!std::isfinite(v)) continue;
          const double wk = map.weight[static_cast<std::size_t>(rr * cols + cc)];
          s += wk * v, ws += wk;
        }
      return ws > 0 ? s / ws : 0.0;
    };
    // Peak: the component pixel of largest smoothed |deviation| (raw on coarse maps).
    int peak = comp.pixels.front();
    double peak_val = 0.0;
    for (auto k : comp.pixels) {
      const double v = coarse ? static_cast<double>(at(k / cols, k % cols)) : smooth(k / cols, k % cols);
      if (std::isfinite(v) && std::abs(v) > std::abs(peak_val)) peak_val = v, peak = k;
    }
    const double sign = peak_val < 0 ? -1.0 : 1.0;
    // Half-height region around the peak (flood fill on the smoothed deviation).
    std::vector<std::int32_t> half;
    {
      std::vector<std::uint8_t> seen(static_cast<std::size_t>(bw * bh), 0);
      std::vector<std::int32_t> stack{peak};
      seen[static_cast<std::size_t>((peak / cols - br0) * bw + (peak % cols - bc0))] = 1;
      while (!stack.empty()) {
        const int k = stack.back();
        stack.pop_back();
        half.push_back(k);
        for (int dr = -1; dr <= 1; ++dr)
          for (int dc = -1; dc <= 1; ++dc) {
            const int rr = k / cols + dr, cc = k % cols + dc;
            if (rr < br0 || rr > br1 || cc < bc0 || cc > bc1) continue;
            auto& s = seen[static_cast<std::size_t>((rr - br0) * bw + (cc - bc0))];
            if (s) continue;
            s = 1;
            const double v = coarse ? static_cast<double>(at(rr, cc)) : smooth(rr, cc);
            if (std::isfinite(v) && sign * v >= 0.5 * std::abs(peak_val)) stack.push_back(rr * cols + cc);
          }
      }
    }
    const double r_half = h * std::sqrt(static_cast<double>(half.size()) / std::numbers::pi);
    // Height: vertex of an isotropic paraboloid fitted to the raw deviation near the peak.
    double height = peak_val;
    {
      const double rad = std::max(1.5 * h, 0.5 * r_half);
      const double pu = map.u[static_cast<std::size_t>(peak)], pv = map.v[static_cast<std::size_t>(peak)];
      Eigen::Matrix4d M = Eigen::Matrix4d::Zero();
      Eigen::Vector4d b = Eigen::Vector4d::Zero();
      int n = 0;
      const int rp = static_cast<int>(std::ceil(rad / h)) + 1;
      for (int r = std::max(br0, peak / cols - rp); r <= std::min(br1, peak / cols + rp); ++r)
        for (int c = std::max(bc0, peak % cols - rp); c <= std::min(bc1, peak % cols + rp); ++c) {
          const int k = r * cols + c;
          const float v = at(r, c);
          if (!std::isfinite(v)) continue;
          const double x = (map.u[k] - pu) / rad, y = (map.v[k] - pv) / rad;
          if (x * x + y * y > 1.0) continue;
          const Eigen::Vector4d e(1, x, y, x * x + y * y);
          M += map.weight[k] * e * e.transpose();
          b += map.weight[k] * v * e;
          ++n;
        }
      if (n >= 6) {
        const Eigen::LDLT<Eigen::Matrix4d> l(M);
        const Eigen::Vector4d p = l.solve(b);
        if (l.info() == Eigen::Success && p.allFinite() && p(3) * sign < 0) {
          const double vx = -p(1) / (2 * p(3)), vy = -p(2) / (2 * p(3));
          if (vx * vx + vy * vy <= 1.0)
            height = p(0) - (p(1) * p(1) + p(2) * p(2)) / (4 * p(3));
          else
            height = p(0);
        } else if (l.info() == Eigen::Success && p.allFinite()) {
          height = p(0);
        }
      } else if (coarse) {
        height = at(peak / cols, peak % cols);
      }
    }
    // On coarse scans (a pixel of one or two samples) a defect whose half-height radius
    // spans fewer than 2.5 samples has too few under its apex for a fit: its extreme
    // vertex is taken below.
    bool apex_fitted = false;
    if (!coarse || r_half >= 2.5 * st.spacing) {
      // The same apex from the vertices over the half-height disc.
      const double rad = std::max(r_half, 2.5 * st.spacing);
      const double pu = map.u[static_cast<std::size_t>(peak)], pv = map.v[static_cast<std::size_t>(peak)];
      const int rp = static_cast<int>(std::ceil(rad / h)) + 1;
      std::vector<Eigen::Vector3d> pts;
      std::vector<ApexSample> near;
      for (int r = std::max(0, peak / cols - rp); r <= std::min(rows - 1, peak / cols + rp); ++r)
        for (int c = std::max(0, peak % cols - rp); c <= std::min(cols - 1, peak % cols + rp); ++c) {
          const int k = r * cols + c;
          if (!(map.weight[k] > 0.0f)) continue;
          pts.clear();
          samples.append(k, pts);
          for (const auto& q : pts) {
            const double refw = local_ref(q.x(), q.y(), static_cast<std::size_t>(k));
            near.push_back({q.x() - pu, q.y() - pv, (q.z() - refw) * map.cos_tilt[k]});
          }
        }
      if (const auto apex = fit_apex_height(near, rad, sign)) height = *apex, apex_fitted = true;
    }
    // Position: deviation-weighted centre of the half-height region, on the surface.
    Eigen::Vector3d pos = Eigen::Vector3d::Zero();
    double ws = 0.0;
    for (auto k : half) {
      const float v = at(k / cols, k % cols);
      const double wk =
          map.weight[static_cast<std::size_t>(k)] * (std::isfinite(v) ? std::abs(v) : 0.0) + 1e-12;
      pos += wk * point_of(k);
      ws += wk;
    }
    pos /= ws;
    if (coarse && local && !apex_fitted) {
      // A pixel spans several samples on a coarse scan and averages a narrow apex
      // away: take the apex from the mesh vertices that fall in the candidate.
      double best = 0.0;
      for (std::size_t i = 0; i < mesh.vertex_count(); ++i) {
        const Eigen::Vector3d q = map.to_map(mesh.vertex(i).cast<double>());
        const long k = map.pixel_of(q.x(), q.y());
        if (k < 0 || labels.at<int>(static_cast<int>(k / cols), static_cast<int>(k % cols)) != ci) continue;
        const double dv = (q.z() - local_ref(q.x(), q.y(), static_cast<std::size_t>(k))) *
                          map.cos_tilt[static_cast<std::size_t>(k)];
        if (sign * dv > best) best = sign * dv, pos = q;
      }
      if (best > std::abs(height)) height = sign * best;
    }
    d.position = map.to_scan(pos.x(), pos.y(), pos.z());
    // Normal: least-squares plane over a normal_patch square around the defect,
    // leaving out the candidate itself.
    {
      const long pk = map.pixel_of(pos.x(), pos.y());
      d.normal = patch_normal(pk >= 0 ? static_cast<int>(pk / cols) : peak / cols,
                              pk >= 0 ? static_cast<int>(pk % cols) : peak % cols, not_surface);
    }
    d.height = height;
    d.diameter = std::max(h, 4.0 * r_half);
    d.area = std::numbers::pi * 0.25 * d.diameter * d.diameter;
    const double snr = std::abs(peak_val) / sigma3;
    d.score = 1.0 - std::exp(-snr / (2.0 * cfg.detection_sigma));
    const double min_extent = std::max(cfg.min_diameter, 2.5 * st.spacing);
    if (!comp.has_deviation && length < min_extent) {
      d.defect_class = protocol::DefectClass::kNoise;
      f.reason = "isolated spike (outlier)";
    } else if (rough_ring) {
      d.defect_class = protocol::DefectClass::kDesignFeature;
      f.reason = "surroundings not a smooth panel (between features)";
    } else if (std::abs(height) < cfg.min_height || snr < cfg.detection_sigma) {
      d.defect_class = protocol::DefectClass::kNoise;
      f.reason = "below the noise-adapted threshold";
    } else {
      d.defect_class = height < 0 ? protocol::DefectClass::kDent : protocol::DefectClass::kBump;
      f.reason = height < 0 ? "depression" : "protrusion";
    }
    const bool is_defect =
        d.defect_class == protocol::DefectClass::kDent || d.defect_class == protocol::DefectClass::kBump;
    const int label =
        is_defect ? static_cast<int>(out.defects.size()) : -2 - static_cast<int>(out.features.size());
    for (auto k : comp.pixels) out.labels[static_cast<std::size_t>(k)] = label;
    d.id = static_cast<std::uint32_t>(is_defect ? out.defects.size() : out.features.size());
    (is_defect ? out.defects : out.features).push_back(std::move(f));
  }
  // Holes: centre on the reference surface, normal from the skin around them.
  for (const HoleRegion& hr : holes) {
    Finding f;
    f.pixels = static_cast<int>(hr.pixels.size());
    protocol::Defect& d = f.defect;
    d.defect_class = protocol::DefectClass::kHole;
    double su = 0.0, sv = 0.0, sw = 0.0;
    int nw = 0;
    for (auto k : hr.pixels) {
      su += map.u0 + (k % cols + 0.5) * h, sv += map.v0 + (k / cols + 0.5) * h;
      if (std::isfinite(ref[static_cast<std::size_t>(k)]) && map.weight[static_cast<std::size_t>(k)] > 0.0f)
        sw += ref[static_cast<std::size_t>(k)], ++nw;
    }
    const double n = static_cast<double>(hr.pixels.size());
    const double pu = su / n, pv = sv / n;
    const long pk = map.pixel_of(pu, pv);
    const int pr = pk >= 0 ? static_cast<int>(pk / cols) : hr.pixels.front() / cols,
              pc = pk >= 0 ? static_cast<int>(pk % cols) : hr.pixels.front() % cols;
    if (nw == 0) {  // no see-through pixel carries the reference: the skin around it
      const int rad = static_cast<int>(std::ceil(0.5 * hr.diameter / h)) + 3;
      for (int r = std::max(0, pr - rad); r <= std::min(rows - 1, pr + rad); ++r)
        for (int c = std::max(0, pc - rad); c <= std::min(cols - 1, pc + rad); ++c) {
          const int k = r * cols + c;
          if (map.weight[k] > 0.0f && !hole_zone.data[k]) sw += map.w[k], ++nw;
        }
    }
    d.position = map.to_scan(pu, pv, nw > 0 ? sw / nw : 0.0);
    d.normal = patch_normal(pr, pc, hole_zone);
    d.diameter = hr.diameter;
    d.area = std::numbers::pi * 0.25 * hr.diameter * hr.diameter;
    d.height = 0.0;  // no surface to measure
    d.score = 1.0 - std::exp(-static_cast<double>(hr.behind) / 4.0);
    char why[96];
    std::snprintf(why, sizeof why, "through-hole: inner structure seen %.0f mm behind the skin",
                  1e3 * hr.backdrop_depth);
    f.reason = why;
    d.id = static_cast<std::uint32_t>(out.defects.size());
    for (auto k : hr.pixels) out.labels[static_cast<std::size_t>(k)] = static_cast<int>(out.defects.size());
    out.defects.push_back(std::move(f));
  }
  // Most confident first; ids in that order.
  std::stable_sort(out.defects.begin(), out.defects.end(),
                   [](const Finding& a, const Finding& b) { return a.defect.score > b.defect.score; });
  {  // labels hold pre-sort indices (kept in id until now)
    std::vector<std::int32_t> old_to_new(out.defects.size());
    for (std::size_t i = 0; i < out.defects.size(); ++i)
      old_to_new[out.defects[i].defect.id] = static_cast<std::int32_t>(i);
    for (auto& l : out.labels)
      if (l >= 0) l = old_to_new[static_cast<std::size_t>(l)];
  }
  {  // One defect split in two candidates (by a dropout, say) is reported once: a less
     // confident report whose centre lies inside a kept one's half-diameter joins it.
    std::vector<std::int32_t> merged_into(out.defects.size(), -1);
    std::vector<Finding> kept;
    for (std::size_t i = 0; i < out.defects.size(); ++i) {
      const auto& di = out.defects[i].defect;
      for (std::size_t j = 0; j < kept.size(); ++j) {
        const auto& dj = kept[j].defect;
        if (di.defect_class == dj.defect_class &&
            (di.position - dj.position).norm() < 0.5 * std::max(di.diameter, dj.diameter)) {
          merged_into[i] = static_cast<std::int32_t>(j);
          break;
        }
      }
      if (merged_into[i] < 0) {
        merged_into[i] = static_cast<std::int32_t>(kept.size());
        kept.push_back(std::move(out.defects[i]));
      }
    }
    out.defects = std::move(kept);
    for (auto& l : out.labels)
      if (l >= 0) l = merged_into[static_cast<std::size_t>(l)];
  }
  std::uint32_t id = 1;
  for (auto& f : out.defects) f.defect.id = id++;
  for (auto& f : out.features) f.defect.id = id++;
  lap("classify");
  return out;
}

}  // namespace dentmark::detect
