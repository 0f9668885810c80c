#include "along_feature.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>

#include "box_mean.h"
#include "dentmark/common/nth_smallest.h"
#include "design_rules.h"
#include "patch_normal.h"

namespace dentmark::detect {
namespace {

constexpr double kFlankNear = 0.013;    // m: flanks start past a 26 mm defect's radius
constexpr double kFlankFar = 0.045;     // m
constexpr double kFlankStep = 0.002;    // m between flank samples (at least a pixel)
constexpr double kEdgeReach = 0.012;    // m from the border zone: left alone
constexpr double kMinDiameter = 0.006;  // m: narrower pieces are the line's own remnants
constexpr double kTensorSigma = 0.006;  // m: the structure tensor's window
constexpr float kCoherence = 0.5f;      // anisotropy of a line's neighbourhood
constexpr double kFlankFull = 0.6;      // share of a flank's samples that must be seen
constexpr double kZoneReach = 0.030;    // m round the design candidates
constexpr float kSpreadSigmas = 4.0f;   // threshold in the flanks' own spread

}  // namespace

namespace {

// dev at (r, c) interpolated bilinearly; NaN off the map or next to a pixel without one.
float sample(const cv::Mat& dev, double r, double c) {
  const int r0 = static_cast<int>(std::floor(r)), c0 = static_cast<int>(std::floor(c));
  if (r0 < 0 || c0 < 0 || r0 + 1 >= dev.rows || c0 + 1 >= dev.cols)
    return std::numeric_limits<float>::quiet_NaN();
  const auto fr = static_cast<float>(r - r0), fc = static_cast<float>(c - c0);
  const float* a = dev.ptr<float>(r0) + c0;
  const float* b = dev.ptr<float>(r0 + 1) + c0;
  return (1 - fr) * ((1 - fc) * a[0] + fc * a[1]) + fr * ((1 - fc) * b[0] + fc * b[1]);
}

// Both flanks of pixel (r, c) along angle a: their medians' difference, their mean (the
// profile), and the flanks' robust spread about their medians; false when a flank is
// under kFlankFull seen.
struct Flanks {
  float gap = 0.0f, profile = 0.0f, spread = 0.0f;
};
bool flanks_at(const cv::Mat& dev, int r, int c, double a, const std::vector<double>& offsets, int need,
               std::vector<float>& ahead, std::vector<float>& behind, Flanks& f) {
  ahead.clear(), behind.clear();
  const double ca = std::cos(a), sa = std::sin(a);
  for (const double s : offsets) {
    const float va = sample(dev, r + s * sa, c + s * ca), vb = sample(dev, r - s * sa, c - s * ca);
    if (std::isfinite(va)) ahead.push_back(va);
    if (std::isfinite(vb)) behind.push_back(vb);
  }
  if (static_cast<int>(ahead.size()) < need || static_cast<int>(behind.size()) < need) return false;
  const float ma = median_in_place(ahead), mb = median_in_place(behind);
  f.gap = std::abs(ma - mb), f.profile = 0.5f * (ma + mb);
  // Spread: the median absolute offset of both flanks from their own medians.
  std::vector<float>& d = ahead;
  for (float& v : d) v = std::abs(v - ma);
  for (const float v : behind) d.push_back(std::abs(v - mb));
  f.spread = static_cast<float>(kMadToSigma) * median_in_place(d);
  return true;
}

}  // namespace

AlongFeature along_feature_residual(const cv::Mat& dev, const cv::Mat& zone, double pixel) {
  const int rows = dev.rows, cols = dev.cols;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  AlongFeature out{cv::Mat(rows, cols, CV_32F, cv::Scalar(nan)),
                   cv::Mat(rows, cols, CV_32F, cv::Scalar(nan))};
  const double step = std::max(kFlankStep, pixel);
  std::vector<double> offsets;  // pixels along the direction, one flank
  for (double s = kFlankNear; s <= kFlankFar + 1e-9; s += step) offsets.push_back(s / pixel);
  const int n = static_cast<int>(offsets.size());
  const int need = static_cast<int>(std::ceil(kFlankFull * n));
  // The structure tensor of the deviation over a Gaussian of kTensorSigma.
  cv::Mat d0 = dev.clone();
  cv::patchNaNs(d0, 0.0);
  cv::Mat gx, gy;
  cv::Sobel(d0, gx, CV_32F, 1, 0, 3);
  cv::Sobel(d0, gy, CV_32F, 0, 1, 3);
  cv::Mat jx = gx.mul(gx), jy = gy.mul(gy), jxy_ = gx.mul(gy);
  const double sg = kTensorSigma / pixel;
  for (cv::Mat* m : {&jx, &jy, &jxy_}) cv::GaussianBlur(*m, *m, cv::Size(0, 0), sg);
#pragma omp parallel
  {
    std::vector<float> ahead, behind;
    ahead.reserve(static_cast<std::size_t>(2 * n)), behind.reserve(static_cast<std::size_t>(n));
#pragma omp for schedule(dynamic, 8)
    for (int r = 0; r < rows; ++r) {
      const std::uint8_t* zr = zone.ptr<std::uint8_t>(r);
      for (int c = 0; c < cols; ++c) {
        const float here = dev.at<float>(r, c);
        if (!zr[c] || !std::isfinite(here)) continue;
        // Along the feature: across the deviation's dominant gradient, where that is
        // clearly one direction; elsewhere there is no line to take out.
        const float jxx = jx.at<float>(r, c), jyy = jy.at<float>(r, c), jxy = jxy_.at<float>(r, c);
        const float tr = jxx + jyy;
        const float aniso = std::sqrt((jxx - jyy) * (jxx - jyy) + 4 * jxy * jxy);
        if (!(tr > 0.0f) || aniso < kCoherence * tr) {
          out.residual.at<float>(r, c) = here;
          out.spread.at<float>(r, c) = 0.0f;
          continue;
        }
        double best_a = 0.5 * std::atan2(2.0 * jxy, static_cast<double>(jxx - jyy)) + 0.5 * std::numbers::pi;
        Flanks best{std::numeric_limits<float>::infinity(), 0.0f, 0.0f}, f;
        if (flanks_at(dev, r, c, best_a, offsets, need, ahead, behind, f)) best = f;
        // Refine the direction: halving steps round it, down to a quarter degree.
        for (double da = 0.05; da > 0.004; da /= 2) {
          const double a0 = best_a;
          for (const double a : {a0 - da, a0 + da})
            if (flanks_at(dev, r, c, a, offsets, need, ahead, behind, f) && f.gap < best.gap)
              best = f, best_a = a;
        }
        if (!std::isfinite(best.gap)) continue;
        out.residual.at<float>(r, c) = here - best.profile;
        out.spread.at<float>(r, c) = best.spread;
      }
    }
  }
  return out;
}

std::vector<Finding> defects_along_features(const AlongFeatureScene& s, const DetectConfig& cfg,
                                            std::vector<std::vector<std::int32_t>>& pixels) {
  const HeightMap& map = s.map;
  const int rows = map.rows, cols = map.cols;
  std::vector<Finding> out;
  if (cv::countNonZero(s.design) == 0) return out;
  const int reach = std::max(1, static_cast<int>(std::lround(kZoneReach / map.pixel)));
  cv::Mat zone;
  cv::dilate(s.design, zone,
             cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * reach + 1, 2 * reach + 1)));
  // Not where a line meets the border: the border's own band crosses its flanks there.
  cv::Mat near_edge;
  const int edge_reach = std::max(1, static_cast<int>(std::lround(kEdgeReach / map.pixel)));
  cv::dilate(s.edge_zone, near_edge,
             cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * edge_reach + 1, 2 * edge_reach + 1)));
  zone &= ~near_edge;
  const AlongFeature along = along_feature_residual(s.dev, zone, map.pixel);
  const cv::Mat& resid = along.residual;
  // The detection scales' means of the residual and their thresholds (deviation.h).
  cv::Mat values(rows, cols, CV_32F), weights(rows, cols, CV_32F);
  for (int k = 0; k < rows * cols; ++k) {
    const float v = resid.ptr<float>()[k];
    const bool ok = std::isfinite(v) && !s.excluded.data[k];
    values.ptr<float>()[k] = ok ? v : 0.0f;
    weights.ptr<float>()[k] = ok ? 1.0f : 0.0f;
  }
  cv::Mat cand(rows, cols, CV_8U, cv::Scalar(0)), finest;
  for (std::size_t i = 0; i < s.scales.size(); ++i) {
    cv::Mat mean;
    const int k = s.scales[i];
    box_mean(values, weights, k, 0.3f * static_cast<float>(k * k), mean);
    const auto thr =
        static_cast<float>(std::max(cfg.detection_sigma * s.scale_sigma[i], 0.5 * cfg.min_height));
    for (int q = 0; q < rows * cols; ++q) {
      const float m = mean.ptr<float>()[q];
      // Where the flanks themselves spread (the steep part of a line that bends, a
      // handle's corner) the profile is uncertain by as much.
      const float t = std::max(thr, kSpreadSigmas * along.spread.ptr<float>()[q]);
      if (std::abs(m) > t && zone.data[q] && !s.excluded.data[q]) cand.data[q] = 255;  // NaN: false
    }
    if (i == 0) finest = mean;
  }
  cv::Mat lab;
  const int n = cv::connectedComponents(cand, lab, 8, CV_32S);
  std::vector<std::vector<std::int32_t>> comps(static_cast<std::size_t>(n));
  for (int q = 0; q < rows * cols; ++q)
    if (const int l = lab.ptr<int>()[q]; l > 0) comps[static_cast<std::size_t>(l)].push_back(q);
  for (int l = 1; l < n; ++l) {
    std::vector<std::int32_t>& px = comps[static_cast<std::size_t>(l)];
    // Away from defects already reported.
    if (std::any_of(px.begin(), px.end(),
                    [&](std::int32_t q) { return s.labels[static_cast<std::size_t>(q)] >= 0; }))
      continue;
    const CandidateShape shape = shape_of(px, map, s.edge_zone);
    if (design_reason(shape, cfg) || shape.length < std::max(cfg.min_diameter, 2.5 * map.pixel)) continue;
    // Peak of the finest scale's mean; the half-height region gives centre and size.
    float peak = 0.0f;
    for (const std::int32_t q : px) {
      const float m = finest.ptr<float>()[q];
      if (std::isfinite(m) && std::abs(m) > std::abs(peak)) peak = m;
    }
    const double snr = std::abs(peak) / std::max(s.sigma3, 1e-9);
    if (std::abs(peak) < cfg.min_height || snr < cfg.detection_sigma) continue;
    double sw = 0.0, su = 0.0, sv = 0.0, swz = 0.0;
    int half = 0;
    for (const std::int32_t q : px) {
      const float m = finest.ptr<float>()[q];
      if (!(m * peak >= 0.5f * peak * peak) || map.weight[static_cast<std::size_t>(q)] <= 0.0f) continue;
      const double w = std::abs(m);
      sw += w, su += w * map.u[static_cast<std::size_t>(q)], sv += w * map.v[static_cast<std::size_t>(q)];
      swz += w * map.w[static_cast<std::size_t>(q)];
      ++half;
    }
    if (sw <= 0.0) continue;
    Finding f;
    f.pixels = static_cast<int>(px.size());
    protocol::Defect& d = f.defect;
    d.position = map.to_scan(su / sw, sv / sw, swz / sw);
    const long pk = map.pixel_of(su / sw, sv / sw);
    const int pr = pk >= 0 ? static_cast<int>(pk / cols) : px.front() / cols;
    const int pc = pk >= 0 ? static_cast<int>(pk % cols) : px.front() % cols;
    d.normal = patch_normal(map, cfg.normal_patch, pr, pc, s.not_surface);
    d.height = peak;
    d.diameter = std::max(map.pixel, 4.0 * std::sqrt(half * map.pixel * map.pixel / std::numbers::pi));
    if (d.diameter < kMinDiameter) continue;
    d.area = std::numbers::pi * 0.25 * d.diameter * d.diameter;
    d.score = 1.0 - std::exp(-snr / (2.0 * cfg.detection_sigma));
    d.defect_class = peak < 0 ? protocol::DefectClass::kDent : protocol::DefectClass::kBump;
    f.reason = peak < 0 ? "depression beside or on a design feature (out of its profile along it)"
                        : "protrusion beside or on a design feature (out of its profile along it)";
    out.push_back(std::move(f));
    pixels.push_back(std::move(px));
  }
  return out;
}

}  // namespace dentmark::detect
