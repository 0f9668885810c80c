#include "deviation.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "box_mean.h"
#include "dentmark/common/nth_smallest.h"
#include "dilate.h"
#include "threads.h"

namespace dentmark::detect {

double sampled_robust_sigma(const cv::Mat& values, const cv::Mat& select) {
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
  return dentmark::robust_sigma(std::move(s));
}

namespace {

// visit(q) for each pixel q of the 3 x 3 round pixel k (k itself included) on a
// rows x cols map.
template <class Visit>
void for_3x3(int k, int rows, int cols, Visit visit) {
  const int r = k / cols, c = k % cols;
  for (int rr = std::max(0, r - 1); rr <= std::min(rows - 1, r + 1); ++rr)
    for (int cc = std::max(0, c - 1); cc <= std::min(cols - 1, c + 1); ++cc) visit(rr * cols + cc);
}

// Clears the pieces of 'grown' that reach the border zone (valid pixels outside the
// interior): beyond a border there is nothing to interpolate from, and a refit without
// them only extrapolates into them.
void keep_border_pieces(cv::Mat& grown, const cv::Mat& valid, const cv::Mat& interior) {
  // Flooded from the pieces' border pixels: the cost is the border pieces' area, not
  // the map's.
  const int rows = grown.rows, cols = grown.cols;
  std::uint8_t* g = grown.ptr<std::uint8_t>();
  const std::uint8_t *vp = valid.ptr<std::uint8_t>(), *ip = interior.ptr<std::uint8_t>();
  std::vector<std::int32_t> stack;
  for (std::int32_t k = 0; k < rows * cols; ++k)
    if (g[k] && vp[k] && !ip[k]) g[k] = 0, stack.push_back(k);
  while (!stack.empty()) {
    const std::int32_t k = stack.back();
    stack.pop_back();
    for_3x3(k, rows, cols, [&](int n) {
      if (g[n]) g[n] = 0, stack.push_back(n);
    });
  }
}

// --- The stages of one fit of deviation_from_reference ---

// Working images of the fits, reused by every iteration.
struct FitImages {
  FitImages(int rows, int cols, std::size_t scales)
      : dz(rows, cols, CV_32F),
        wv(rows, cols, CV_32F),
        valid(rows, cols, CV_8U),
        num(scales),
        off_skin(rows, cols, CV_8U, cv::Scalar(0)) {}
  cv::Mat dz;                // CV_32F: the deviation where valid, 0 elsewhere; then its weighted median
  cv::Mat wv;                // CV_32F: the map's weight where valid, 0 elsewhere
  cv::Mat dm;                // CV_32F: the 3 x 3 median of dz
  cv::Mat valid;             // CV_8U: 255 where the map and the reference both have a height
  std::vector<cv::Mat> num;  // per scale: the windowed mean deviation, NaN where too empty
  // Pixels found not to be skin in any fit so far: spikes, and pixels more than hole_depth
  // off it (a hole's backdrop, a handle's top). They stay out of every later fit: left
  // to the candidates, which change from one fit to the next, they come back into every
  // other fit and pull it by their weight times their distance (a 10 mm spike moves a
  // whole window's reference by ~0.1 mm).
  cv::Mat off_skin;
  cv::Mat off_skin_grown, grown;
};

// Deviation from the reference along the normal (out.along_normal, NaN where either has
// no height); where it is valid, also the deviation and weight that the box filters
// average (0 elsewhere).
void deviation_along_normal(const HeightMap& map, const std::vector<float>& ref, Deviation& out,
                            FitImages& im) {
  float *d = out.along_normal.ptr<float>(), *dzp = im.dz.ptr<float>(), *wvp = im.wv.ptr<float>();
  std::uint8_t* vp = im.valid.ptr<std::uint8_t>();
#pragma omp parallel for schedule(static)
  for (std::int64_t k = 0; k < static_cast<std::int64_t>(map.size()); ++k) {
    const bool ok = map.weight[k] > 0.0f && std::isfinite(ref[k]);
    d[k] = ok ? (map.w[k] - ref[k]) * map.cos_tilt[k] : std::numeric_limits<float>::quiet_NaN();
    dzp[k] = ok ? d[k] : 0.0f;
    wvp[k] = ok ? map.weight[k] : 0.0f;
    vp[k] = ok ? 255 : 0;
  }
}

// The median of the valid pixels in k's 3 x 3 (k itself included) that are no spikes;
// false with under 3 of them.
bool median_of_skin(const FitImages& im, const std::uint8_t* spikes, int k, std::vector<float>& scratch,
                    float& median) {
  const float* dzp = im.dz.ptr<float>();
  const std::uint8_t* vp = im.valid.ptr<std::uint8_t>();
  scratch.clear();
  for_3x3(k, im.dz.rows, im.dz.cols, [&](int q) {
    if (vp[q] && !spikes[q]) scratch.push_back(dzp[q]);
  });
  if (scratch.size() < 3) return false;
  median = static_cast<float>(median_of(scratch));
  return true;
}

// The valid pixels next to (8-connected) the pixels in `from` that are no spikes, each
// once. listed: all 0, one per pixel, and all 0 again on return.
std::vector<int> skin_next_to(const std::vector<int>& from, const FitImages& im, const std::uint8_t* spikes,
                              std::vector<std::uint8_t>& listed) {
  const std::uint8_t* vp = im.valid.ptr<std::uint8_t>();
  std::vector<int> out;
  for (const int k : from)
    for_3x3(k, im.dz.rows, im.dz.cols, [&](int q) {
      if (vp[q] && !spikes[q] && !listed[static_cast<std::size_t>(q)])
        listed[static_cast<std::size_t>(q)] = 1, out.push_back(q);
    });
  for (const int q : out) listed[static_cast<std::size_t>(q)] = 0;
  return out;
}

// A cluster of thrown samples (a flying pixel's needle triangles reach into the pixels
// round it; two fly side by side) lifts its pixels' 3 x 3 medians with it, and only its
// highest pixels pass the spike test: the rest stayed in the box means as specks of
// 6-8 mm, 40-80 um high (3 on one of the independent generator's doors with 0.33 %
// flying pixels). So from each spike in the skin (the median of its neighbours that are
// no spikes within spike_height of the reference; not a defect's flank, nor the band a
// reference leaves along a line), a neighbour in the skin is a spike too where it is off
// that median by spike_height, again until none is added (at most kSpikePasses times);
// then spikes and their neighbours take that median (im.dm).
constexpr int kSpikePasses = 4;
void grow_spike_clusters(const cv::Mat& along_normal, float spike_height, std::uint8_t* spikes,
                         FitImages& im) {
  const std::size_t n = im.dz.total();
  const float* d = along_normal.ptr<float>();
  std::vector<float> scratch;
  const auto in_skin = [&](int k, float& m) {
    return median_of_skin(im, spikes, k, scratch, m) && std::abs(m) < spike_height;
  };
  std::vector<int> all, fresh;
  for (std::size_t k = 0; k < n; ++k) {
    if (!spikes[k]) continue;
    all.push_back(static_cast<int>(k));
    if (float m = 0.0f; in_skin(static_cast<int>(k), m)) fresh.push_back(static_cast<int>(k));
  }
  std::vector<std::uint8_t> listed(n, 0);
  for (int pass = 0; pass < kSpikePasses && !fresh.empty(); ++pass) {
    std::vector<int> found;
    for (const int k : skin_next_to(fresh, im, spikes, listed))
      if (float m = 0.0f; in_skin(k, m) && std::abs(d[k] - m) > spike_height) found.push_back(k);
    for (const int k : found) spikes[k] = 255;  // after the pass: the same whatever the order
    all.insert(all.end(), found.begin(), found.end());
    fresh = std::move(found);
  }
  std::vector<int> touched = skin_next_to(all, im, spikes, listed);
  touched.insert(touched.end(), all.begin(), all.end());
  float* dmp = im.dm.ptr<float>();
  for (const int k : touched)
    if (float m = 0.0f; median_of_skin(im, spikes, k, scratch, m)) dmp[k] = m;
}

// The deviation's noise (out.noise: robust sigma over the interior), and its outlier
// spikes (out.spikes): pixels far from their 3 x 3 median. A lone spike cannot survive
// the median; a defect of a few pixels can. Spikes and pixels more than hole_depth off
// the reference join im.off_skin; im.dz becomes the weighted median deviation. At the
// last fit the spikes grow over thrown clusters (grow_spike_clusters; out.median_spikes
// keeps those of the median test alone); not before, so the reference's fits do not
// change (grown along a line's band, pixels left the fit and moved it: 5 defects beside
// lines were lost over 80 doors).
void mark_spikes(const HeightMap& map, const cv::Mat& interior, const std::vector<int>& scales,
                 const DetectConfig& cfg, bool last_fit, Deviation& out, FitImages& im) {
  // (The noise's σ meanwhile: both are serial.)
  const bool median = scales.front() >= 3;
  detail::side_by_side([&] { out.noise = sampled_robust_sigma(out.along_normal, interior); },
                       [&] {
                         if (median)
                           cv::medianBlur(im.dz, im.dm, 3);
                         else
                           im.dz.copyTo(im.dm);
                       });
  const float* d = out.along_normal.ptr<float>();
  const float* wvp = im.wv.ptr<float>();
  const std::uint8_t* vp = im.valid.ptr<std::uint8_t>();
  float* dzp = im.dz.ptr<float>();  // the weighted median deviation, in dz's place
  const float* dmp = im.dm.ptr<float>();
  std::uint8_t *sp = out.spikes.ptr<std::uint8_t>(), *osk = im.off_skin.ptr<std::uint8_t>();
  const auto spike_height =
      static_cast<float>(std::max(cfg.detection_sigma * out.noise, 0.5 * cfg.min_height));
  const auto far_off = static_cast<float>(cfg.hole_depth);
#pragma omp parallel for schedule(static)
  for (std::int64_t k = 0; k < static_cast<std::int64_t>(map.size()); ++k) {
    // A spike stands out of its neighbourhood by more than the neighbourhood stands out
    // of the reference; a narrow defect's apex (its neighbours deep too) does not.
    const float off = std::abs(dzp[k] - dmp[k]);
    sp[k] = vp[k] && off > spike_height && off > 2.0f * std::abs(dmp[k]) ? 255 : 0;
  }
  if (last_fit) {
    out.median_spikes = out.spikes.clone();
    if (median) grow_spike_clusters(out.along_normal, spike_height, sp, im);
  }
#pragma omp parallel for schedule(static)
  for (std::int64_t k = 0; k < static_cast<std::int64_t>(map.size()); ++k) {
    osk[k] |= sp[k] | (std::abs(d[k]) > far_off ? 255 : 0);  // NaN compares false
    dzp[k] = wvp[k] * dmp[k];
  }
}

// Candidates (out.candidates): valid pixels whose windowed mean of the weighted median
// deviation stands out of its scale's noise (out.scale_sigma, robust sigma over the
// interior) at one scale or more, by detection_sigma of it and at least half min_height.
// A window counts where it is at least 30 % full.
void mark_candidates(const HeightMap& map, const cv::Mat& interior, const std::vector<int>& scales,
                     const DetectConfig& cfg, Deviation& out, FitImages& im) {
  out.candidates.create(map.rows, map.cols, CV_8U);
  std::uint8_t* cp = out.candidates.ptr<std::uint8_t>();
  const std::uint8_t* vp = im.valid.ptr<std::uint8_t>();
  std::vector<double>& scale_sigma = out.scale_sigma;
  // The windowed means, then their σ, side by side (each is serial).
  for (std::size_t s = 0; s < scales.size(); ++s)
    box_mean(im.dz, im.wv, scales[s], 0.3f * static_cast<float>(scales[s] * scales[s]), im.num[s]);
  detail::for_each_part(scales.size(),
                        [&](std::size_t s) { scale_sigma[s] = sampled_robust_sigma(im.num[s], interior); });
  // One pass over the scales' means.
  std::vector<const float*> means(scales.size());
  std::vector<float> thresholds(scales.size());
  for (std::size_t s = 0; s < scales.size(); ++s) {
    means[s] = im.num[s].ptr<float>();
    thresholds[s] = static_cast<float>(std::max(cfg.detection_sigma * scale_sigma[s], 0.5 * cfg.min_height));
  }
#pragma omp parallel for schedule(static)
  for (std::int64_t q = 0; q < static_cast<std::int64_t>(map.size()); ++q) {
    bool out_of_noise = false;
    for (std::size_t s = 0; s < means.size(); ++s)
      out_of_noise = out_of_noise || std::abs(means[s][q]) > thresholds[s];  // NaN compares false
    cp[q] = vp[q] && out_of_noise ? 255 : 0;
  }
}

// The next fit's weights: candidates (grown by 2 pixels) and pixels off the skin leave
// it. On a chart, candidates reaching a border stay: its borders are the chart's cut or
// the panel's edge at 30-55 degrees to the map, where, with nothing beyond to interpolate
// from, a fit without them only extrapolates into them (a tube's edge: ~20 um after the
// first fit, -0.6 mm after the third). On a single view's map its borders are flanges,
// openings and the edges of holes, and are left out as before (kept in, 2 of 3 defects
// were found beside stray vertices, and one of 2 on the small door). Spends
// out.candidates (off a chart).
void weights_for_next_fit(const HeightMap& map, const cv::Mat& interior, bool keep_border_candidates,
                          Deviation& out, FitImages& im, std::vector<float>& ref_weights) {
  const cv::Mat square = cv::getStructuringElement(cv::MORPH_RECT, {5, 5});
  if (keep_border_candidates) {
    dilate_in_strips(out.candidates, im.grown, square);
    keep_border_pieces(im.grown, im.valid, interior);
    dilate_in_strips(im.off_skin, im.off_skin_grown, square);
    im.grown |= im.off_skin_grown;
  } else {
    out.candidates |= im.off_skin;  // (this iteration's candidates are not needed after this)
    dilate_in_strips(out.candidates, im.grown, square);
  }
  const std::uint8_t* g = im.grown.ptr<std::uint8_t>();
#pragma omp parallel for schedule(static)
  for (std::int64_t k = 0; k < static_cast<std::int64_t>(map.size()); ++k)
    ref_weights[k] = g[k] ? 0.0f : map.weight[k];
}

}  // namespace

std::vector<int> detection_scales(double pixel) {
  std::vector<int> scales;
  for (double s : {0.003, 0.007, 0.015}) {
    int k = std::max(1, static_cast<int>(std::lround(s / pixel)));
    if (k % 2 == 0) ++k;
    if (std::find(scales.begin(), scales.end(), k) == scales.end()) scales.push_back(k);
  }
  return scales;
}

Deviation deviation_from_reference(const HeightMap& map, ReferenceSurface& reference, const cv::Mat& interior,
                                   const std::vector<int>& scales, const DetectConfig& cfg,
                                   bool keep_border_candidates) {
  Deviation out;
  out.along_normal.create(map.rows, map.cols, CV_32F);
  out.spikes.create(map.rows, map.cols, CV_8U);
  out.scale_sigma.assign(scales.size(), 0.0);
  FitImages im(map.rows, map.cols, scales.size());
  std::vector<float> ref_weights(map.weight);
  const int iterations = std::max(1, cfg.reference_iterations);
  for (int it = 0; it < iterations; ++it) {
    // After the first: only where the candidates changed.
    const std::vector<float>& ref = reference.fit(ref_weights);
    deviation_along_normal(map, ref, out, im);
    mark_spikes(map, interior, scales, cfg, it + 1 == iterations, out, im);
    mark_candidates(map, interior, scales, cfg, out, im);
    if (it + 1 < iterations)
      weights_for_next_fit(map, interior, keep_border_candidates, out, im, ref_weights);
  }
  return out;
}

}  // namespace dentmark::detect
