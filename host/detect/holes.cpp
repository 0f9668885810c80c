#include "holes.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <opencv2/imgproc.hpp>

#include "components.h"
#include "dentmark/common/nth_smallest.h"

namespace dentmark::detect {
namespace {

// --- The stages of find_holes ---

// The regions without skin that may be holes: enclosed (not touching the border), of
// two pixels or more (one pixel seen deep is an outlier spike behind the skin, its few
// triangles holding the pixel's front: a hole shows its backdrop over several pixels),
// and no wider than max_diameter. index[label] is the candidate's number, -1 for none;
// their pixels are gathered later, once they have the evidence (most never do: a dense
// scan has thousands of one-pixel gaps).
struct HoleCandidates {
  std::vector<int> index;
  std::vector<HoleRegion> regions;  // diameter set
  std::vector<int> area;            // pixels
};

HoleCandidates hole_candidates(const Components& regions, double px_area, double max_diameter) {
  HoleCandidates hc;
  hc.index.assign(static_cast<std::size_t>(regions.count), -1);
  for (std::size_t i = 1; i < hc.index.size(); ++i) {
    if (regions.touches_border[i] || regions.area[i] < 2) continue;
    const double d = 2.0 * std::sqrt(regions.area[i] * px_area / std::numbers::pi);
    if (d > max_diameter) continue;
    hc.index[i] = static_cast<int>(hc.regions.size());
    hc.regions.push_back({{}, 0, d, 0.0, {}});
    hc.area.push_back(regions.area[i]);
  }
  return hc;
}

// The evidence: points behind the skin (map.behind, and the deep pixels' own points)
// traced back towards the sensor (or straight along the map normal when the scan frame
// is not the sensor's) until they reach the skin's level: through a candidate, they were
// seen through it. Per candidate, the depths behind the skin of the points seen through
// it, and the deep pixels among them.
struct SeenThrough {
  std::vector<std::vector<float>> depths;
  std::vector<std::vector<std::int32_t>> seen_deep;
};

SeenThrough trace_through(const HeightMap& map, const cv::Mat& deep, const std::vector<float>& ref,
                          const int* lab, const HoleCandidates& hc, double behind_depth) {
  const int rows = map.rows, cols = map.cols;
  SeenThrough st;
  st.depths.resize(hc.regions.size());
  st.seen_deep.resize(hc.regions.size());
  const Eigen::Vector3d up(0.0, 0.0, 1.0);
  const double step = 0.5 * map.pixel;
  // A ray that has seen no skin yet and has risen to the highest skin's level can meet
  // no candidate after some skin below it: it is traced no further.
  float skin_top_f = -std::numeric_limits<float>::infinity();
#pragma omp parallel for schedule(static) reduction(max : skin_top_f)
  for (std::int32_t k = 0; k < rows * cols; ++k)
    if (map.weight[static_cast<std::size_t>(k)] > 0.0f && std::isfinite(ref[static_cast<std::size_t>(k)]) &&
        !deep.data[k])
      skin_top_f = std::max(skin_top_f, ref[static_cast<std::size_t>(k)]);
  const double skin_top = skin_top_f;
  auto trace = [&](const Eigen::Vector3d& b, std::int32_t deep_pixel) {
    const Eigen::Vector3d dir = map.has_viewpoint ? (map.viewpoint - b).normalized() : up;
    if (!(dir.z() > 0.05)) return;
    double last_ref = std::numeric_limits<double>::quiet_NaN();
    Eigen::Vector3d p = b;
    for (int i = 0; i < 600; ++i, p += step * dir) {
      const long k = map.pixel_of(p.x(), p.y());
      if (k < 0 || (!std::isfinite(last_ref) && p.z() >= skin_top - behind_depth)) return;
      const int c = lab[k] > 0 ? hc.index[static_cast<std::size_t>(lab[k])] : -1;
      if (c >= 0) {
        if (std::isfinite(last_ref) && p.z() >= last_ref - behind_depth) {
          st.depths[static_cast<std::size_t>(c)].push_back(static_cast<float>(last_ref - b.z()));
          if (deep_pixel >= 0) st.seen_deep[static_cast<std::size_t>(c)].push_back(deep_pixel);
          return;
        }
        continue;
      }
      if (map.weight[static_cast<std::size_t>(k)] > 0.0f && std::isfinite(ref[static_cast<std::size_t>(k)]) &&
          !deep.data[k]) {
        if (p.z() >= ref[static_cast<std::size_t>(k)] - behind_depth) return;  // hidden by the skin
        last_ref = ref[static_cast<std::size_t>(k)];
      }
    }
  };
  for (const auto& b : map.behind) trace(b.cast<double>(), -1);
  for (std::int32_t k = 0; k < rows * cols; ++k)
    if (deep.data[k]) {
      const auto q = static_cast<std::size_t>(k);
      trace({map.u[q], map.v[q], map.w[q]}, k);
    }
  return st;
}

// Ringed by skin: of the pixels within two of the region (its label `own` left out), at
// least 70 % are surface within behind_depth of the reference.
bool ringed_by_skin(const HeightMap& map, const float* dev, const int* lab, const HoleRegion& region,
                    double behind_depth) {
  const int rows = map.rows, cols = map.cols;
  int ring = 0, skin = 0;
  const int own = lab[region.pixels.front()];
  std::vector<std::int32_t> seen;
  for (auto k : region.pixels)
    for (int dr = -2; dr <= 2; ++dr)
      for (int dc = -2; dc <= 2; ++dc) {
        const int r = k / cols + dr, cc = k % cols + dc;
        if (r < 0 || cc < 0 || r >= rows || cc >= cols) continue;
        const int q = r * cols + cc;
        if (lab[q] == own) continue;
        seen.push_back(q);
      }
  std::sort(seen.begin(), seen.end());
  seen.erase(std::unique(seen.begin(), seen.end()), seen.end());
  for (auto q : seen) {
    ++ring;
    if (map.weight[static_cast<std::size_t>(q)] > 0.0f && std::isfinite(dev[q]) &&
        std::abs(dev[q]) <= behind_depth)
      ++skin;
  }
  return ring > 0 && skin >= 0.7 * ring;
}

}  // namespace

std::vector<HoleRegion> find_holes(const HeightMap& map, const cv::Mat& deviation,
                                   const std::vector<float>& ref, double behind_depth, double max_diameter) {
  const int rows = map.rows, cols = map.cols;
  cv::Mat weight(rows, cols, CV_32F, const_cast<float*>(map.weight.data()));
  const cv::Mat deep = deviation < static_cast<float>(-behind_depth);  // NaN compares false
  const cv::Mat region = (weight <= 0.0f) | deep;
  const Components regions = label_components(region, 8);
  const int* lab = regions.labels.ptr<int>();
  const float* dev = deviation.ptr<float>();
  HoleCandidates hc = hole_candidates(regions, map.pixel * map.pixel, max_diameter);
  if (hc.regions.empty()) return {};
  SeenThrough st = trace_through(map, deep, ref, lab, hc, behind_depth);

  // Evident: at least 3 points seen through, and one for every 10 pixels; their pixels
  // gathered.
  std::vector<HoleRegion>& cand = hc.regions;
  std::vector<char> evident(cand.size(), 0);
  bool any = false;
  for (std::size_t c = 0; c < cand.size(); ++c) {
    const auto evidence = static_cast<int>(st.depths[c].size());
    evident[c] = evidence >= 3 && 10 * evidence >= hc.area[c];
    any = any || evident[c];
  }
  if (!any) return {};
  for (std::int32_t k = 0; k < rows * cols; ++k)
    if (lab[k] > 0) {
      const int c = hc.index[static_cast<std::size_t>(lab[k])];
      if (c >= 0 && evident[static_cast<std::size_t>(c)])
        cand[static_cast<std::size_t>(c)].pixels.push_back(k);
    }

  std::vector<HoleRegion> holes;
  for (std::size_t c = 0; c < cand.size(); ++c) {
    if (!evident[c] || !ringed_by_skin(map, dev, lab, cand[c], behind_depth)) continue;
    auto& d = st.depths[c];
    cand[c].behind = static_cast<int>(d.size());
    cand[c].seen_deep = std::move(st.seen_deep[c]);
    cand[c].backdrop_depth = median_in_place(d);
    holes.push_back(std::move(cand[c]));
  }
  return holes;
}

}  // namespace dentmark::detect
