#include "along_feature.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <numeric>
#include <opencv2/imgproc.hpp>

#include "box_mean.h"
#include "dentmark/common/nth_smallest.h"
#include "design_rules.h"
#include "deviation.h"
#include "findings.h"
#include "patch_normal.h"

namespace dentmark::detect {
namespace {

constexpr double kFlankNear = 0.013;       // m: flanks start past a 26 mm defect's radius
constexpr double kFlankFar = 0.045;        // m
constexpr double kFlankStep = 0.002;       // m between flank samples (at least a pixel)
constexpr double kWallSlope = 0.8;         // steeper than a character line's flank (up to ~0.5)
constexpr double kWallReach = 0.003;       // m round a wall: its rounded rims
constexpr double kWallFoot = 0.005;        // m round a grown wall: no defect's peak is read there
constexpr double kPlainEdgeReach = 0.035;  // m from the border zone: no plain deviation
constexpr double kEdgeReach = 0.012;       // m from the border zone: left alone
constexpr double kMinDiameter = 0.006;     // m: narrower pieces are the line's own remnants
constexpr double kTensorSigma = 0.006;     // m: the structure tensor's window
constexpr double kSlopeSigma = 0.020;      // m: the panel's own slope, taken out of the gradients
constexpr float kCoherence = 0.5f;         // anisotropy of a line's neighbourhood
constexpr double kFlankFull = 0.6;         // share of a flank's samples that must be seen
constexpr double kZoneReach = 0.030;       // m round the design candidates
constexpr float kSpreadSigmas = 4.0f;      // threshold in the flanks' own spread
constexpr double kJoinGap = 0.005;         // m: findings of one sign closer than this are one defect
constexpr double kOutlierScatter = 5.0;    // a thrown point: off its neighbours' plane by this x their rms

// m (CV_32F) at (r, c) interpolated bilinearly; NaN off the map or next to a pixel without
// a value.
float sample(const cv::Mat& m, double r, double c) {
  const int r0 = static_cast<int>(std::floor(r)), c0 = static_cast<int>(std::floor(c));
  if (r0 < 0 || c0 < 0 || r0 + 1 >= m.rows || c0 + 1 >= m.cols)
    return std::numeric_limits<float>::quiet_NaN();
  const auto fr = static_cast<float>(r - r0), fc = static_cast<float>(c - c0);
  const float* a = m.ptr<float>(r0) + c0;
  const float* b = m.ptr<float>(r0 + 1) + c0;
  return (1 - fr) * ((1 - fc) * a[0] + fc * a[1]) + fr * ((1 - fc) * b[0] + fc * b[1]);
}

// The surface's profile along angle a through pixel (r, c): a quadratic in the distance
// along the line, fitted to the heights of both flanks, the samples further than 3 sigma
// from the first fit left out of the second. The quadratic takes the panel's slope and
// curvature along the line, which a mean of the flanks would leave in; the pixel's own
// height is not in the fit, so a defect does not pull it. False when a flank is under
// kFlankFull seen or its outer half under half seen.
struct Profile {
  float at_pixel = 0.0f;  // the fit's height at the pixel (m)
  float spread = 0.0f;    // kMadToSigma x the median absolute residual of the fit (m)
  float gap = 0.0f;       // how far apart the two flanks' own lines pass the pixel (m)
};
struct FlankSample {
  double s = 0.0;  // m along the line
  float w = 0.0f;  // height
};
bool fit_quadratic(const std::vector<FlankSample>& xs, float cut, double& a0, std::vector<float>& residual) {
  Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
  Eigen::Vector3d atb = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < xs.size(); ++i) {
    if (!(std::abs(residual[i]) <= cut)) continue;
    const Eigen::Vector3d row(1.0, xs[i].s, xs[i].s * xs[i].s);
    ata += row * row.transpose(), atb += row * static_cast<double>(xs[i].w);
  }
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(ata);
  if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-12)) return false;
  const Eigen::Vector3d x = ldlt.solve(atb);
  for (std::size_t i = 0; i < xs.size(); ++i)
    residual[i] = static_cast<float>(xs[i].w - (x[0] + x[1] * xs[i].s + x[2] * xs[i].s * xs[i].s));
  a0 = x[0];
  return true;
}
// The least-squares line through one flank's samples (side: +1 ahead, -1 behind) whose
// residual is within cut, at the pixel (s = 0); NaN with under 2 of them.
double flank_line_at_pixel(const std::vector<FlankSample>& xs, const std::vector<float>& residual, float cut,
                           double side) {
  double n = 0.0, ss = 0.0, sw = 0.0, sss = 0.0, ssw = 0.0;
  for (std::size_t i = 0; i < xs.size(); ++i) {
    if (xs[i].s * side <= 0.0 || !(std::abs(residual[i]) <= cut)) continue;
    const double x = xs[i].s, y = xs[i].w;
    n += 1.0, ss += x, sw += y, sss += x * x, ssw += x * y;
  }
  const double det = n * sss - ss * ss;
  if (n < 2.0 || !(det > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  return (sw * sss - ss * ssw) / det;
}
bool profile_at(const cv::Mat& height, int r, int c, double a, const std::vector<double>& offsets,
                double pixel, int need, std::vector<FlankSample>& xs, std::vector<float>& residual,
                std::vector<float>& scratch, Profile& out) {
  xs.clear();
  const double ca = std::cos(a), sa = std::sin(a);
  int ahead = 0, behind = 0, ahead_far = 0, behind_far = 0;
  const std::size_t half = offsets.size() / 2;
  for (std::size_t i = 0; i < offsets.size(); ++i) {
    const double s = offsets[i];
    const float va = sample(height, r + s * sa, c + s * ca), vb = sample(height, r - s * sa, c - s * ca);
    if (std::isfinite(va)) xs.push_back({s * pixel, va}), ++ahead, ahead_far += i >= half;
    if (std::isfinite(vb)) xs.push_back({-s * pixel, vb}), ++behind, behind_far += i >= half;
  }
  // Both flanks reach out: a profile is interpolated, never extrapolated from one side.
  const int need_far = static_cast<int>((offsets.size() - half) / 2);
  if (ahead < need || behind < need || ahead_far < need_far || behind_far < need_far) return false;
  residual.assign(xs.size(), 0.0f);
  double a0 = 0.0;
  float sigma = 0.0f;
  for (int pass = 0; pass < 2; ++pass) {
    if (!fit_quadratic(xs, pass == 0 ? std::numeric_limits<float>::infinity() : std::max(3.0f * sigma, 1e-6f),
                       a0, residual))
      return false;
    scratch.resize(residual.size());
    std::transform(residual.begin(), residual.end(), scratch.begin(), [](float v) { return std::abs(v); });
    sigma = static_cast<float>(kMadToSigma) * median_in_place(scratch);
  }
  // Each flank's own line, at the pixel: where the flanks disagree (a handle's end, a
  // line that bends or stops) the profile through the pixel is uncertain by as much.
  const float cut = std::max(3.0f * sigma, 1e-6f);
  out.at_pixel = static_cast<float>(a0), out.spread = sigma;
  out.gap = static_cast<float>(
      std::abs(flank_line_at_pixel(xs, residual, cut, 1.0) - flank_line_at_pixel(xs, residual, cut, -1.0)));
  return std::isfinite(out.gap);
}

// The least-squares plane through the mean points of the surface pixels round (r, c)
// (3 x 3, with (r, c) itself unless leave_out_centre; none set in skip, CV_8U, which may
// be empty; with drop_worst, refitted without the point furthest from the first fit when
// that point is far off the others' plane): its height at (u, v) less w0, and its points'
// rms about it. False with too few points for a plane (a lone pixel, a line of them).
struct LocalPlane {
  double height = 0.0;  // m, less w0 (w0 near the heights keeps the sums' precision)
  double rms = 0.0;     // m
  int points = 0;
};
bool plane_round(const HeightMap& map, int r, int c, double u, double v, double w0, const cv::Mat& skip,
                 bool leave_out_centre, LocalPlane& out, bool drop_worst = false) {
  Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
  Eigen::Vector3d atb = Eigen::Vector3d::Zero();
  std::array<Eigen::Vector3d, 9> rows;
  std::array<double, 9> dws{};
  double ww = 0.0;
  out.points = 0;
  for (int rr = std::max(0, r - 1); rr <= std::min(map.rows - 1, r + 1); ++rr)
    for (int cc = std::max(0, c - 1); cc <= std::min(map.cols - 1, c + 1); ++cc) {
      const std::size_t q =
          static_cast<std::size_t>(rr) * static_cast<std::size_t>(map.cols) + static_cast<std::size_t>(cc);
      if ((leave_out_centre && rr == r && cc == c) || !(map.weight[q] > 0.0f) ||
          (!skip.empty() && skip.data[q]))
        continue;
      const Eigen::Vector3d row(1.0, (map.u[q] - u) / map.pixel, (map.v[q] - v) / map.pixel);
      const double dw = static_cast<double>(map.w[q]) - w0;
      ata += row * row.transpose(), atb += row * dw;
      ww += dw * dw;
      rows[static_cast<std::size_t>(out.points)] = row, dws[static_cast<std::size_t>(out.points)] = dw;
      ++out.points;
    }
  Eigen::LDLT<Eigen::Matrix3d> ldlt(ata);
  if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-3)) return false;
  const Eigen::Vector3d x = ldlt.solve(atb);
  // Σ residual² = Σ dw² − xᵀ Aᵀb at the least-squares solution.
  const auto rms_of = [](double sum_w2, const Eigen::Vector3d& fit, const Eigen::Vector3d& sum_bw, int n) {
    return n > 3 ? std::sqrt(std::max(0.0, sum_w2 - fit.dot(sum_bw)) / (n - 3)) : 0.0;
  };
  out.height = x[0];
  out.rms = rms_of(ww, x, atb, out.points);
  if (!drop_worst || out.points <= 4) return true;
  std::size_t worst = 0;
  for (std::size_t i = 1; i < static_cast<std::size_t>(out.points); ++i)
    if (std::abs(dws[i] - rows[i].dot(x)) > std::abs(dws[worst] - rows[worst].dot(x))) worst = i;
  const Eigen::Matrix3d ata_rest = ata - rows[worst] * rows[worst].transpose();
  const Eigen::Vector3d atb_rest = atb - rows[worst] * dws[worst];
  ldlt.compute(ata_rest);
  if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-3)) return true;
  const Eigen::Vector3d y = ldlt.solve(atb_rest);
  const double rms_rest = rms_of(ww - dws[worst] * dws[worst], y, atb_rest, out.points - 1);
  // Only a point off the others' plane by far more than they scatter about it (a thrown
  // sample): a curved surface bends every point about a plane, the worst only somewhat
  // more than the rest.
  if (std::abs(dws[worst] - rows[worst].dot(y)) > kOutlierScatter * rms_rest)
    out.height = y[0], out.rms = rms_rest, --out.points;
  return true;
}

// The least-squares quadric w = a + b x + c y + d x^2 + e x y + f y^2 through the mean
// points of the surface pixels round (r, c) (3 x 3, none set in skip), x and y in pixels
// from (u, v): its height a there. False with under 8 points (with 7, one degree of
// freedom is left and the fit follows their noise) or ill-conditioned.
bool quadric_round(const HeightMap& map, int r, int c, double u, double v, const cv::Mat& skip,
                   double& height) {
  using Vector6d = Eigen::Matrix<double, 6, 1>;
  Eigen::Matrix<double, 6, 6> ata = Eigen::Matrix<double, 6, 6>::Zero();
  Vector6d atb = Vector6d::Zero();
  int points = 0;
  for (int rr = std::max(0, r - 1); rr <= std::min(map.rows - 1, r + 1); ++rr)
    for (int cc = std::max(0, c - 1); cc <= std::min(map.cols - 1, c + 1); ++cc) {
      const std::size_t q =
          static_cast<std::size_t>(rr) * static_cast<std::size_t>(map.cols) + static_cast<std::size_t>(cc);
      if (!(map.weight[q] > 0.0f) || skip.data[q]) continue;
      const double x = (map.u[q] - u) / map.pixel, y = (map.v[q] - v) / map.pixel;
      Vector6d row;
      row << 1.0, x, y, x * x, x * y, y * y;
      ata += row * row.transpose(), atb += row * static_cast<double>(map.w[q]);
      ++points;
    }
  if (points < 8) return false;
  const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(ata);
  if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-4)) return false;
  height = ldlt.solve(atb)[0];
  return true;
}

// The map's heights at the pixels' centres (CV_32F, m; NaN where no surface): the
// quadric through the mean points of the pixel and its surface neighbours (3 x 3), at
// the centre, or their plane where too few are surface for a quadric. A pixel's mean
// point lies anywhere in it, and on a character line's flank (slopes up to 1:3) its
// height alone is off by up to a sixth of a pixel's size. A plane through the points
// takes the slope out but not the curvature: on a line's shoulders (~0.1 /mm) it is
// off by 10-45 um, by how far the points lie from the centre, which changes with the
// sampling's phase in the pixel grid. Either error reads along the line as a streak of
// false defects. Pixels set in skip (CV_8U: spikes, holes) have no height and are in no
// fit: one thrown sample moves its pixel's mean point by millimetres, and every profile
// whose flank passes it.
enum class LocalFit { kPlane, kQuadric };
cv::Mat heights_of(const HeightMap& map, const cv::Mat& skip, LocalFit fit) {
  cv::Mat h(map.rows, map.cols, CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
#pragma omp parallel for schedule(static)
  for (int r = 0; r < map.rows; ++r) {
    float* hr = h.ptr<float>(r);
    for (int c = 0; c < map.cols; ++c) {
      const std::size_t k =
          static_cast<std::size_t>(r) * static_cast<std::size_t>(map.cols) + static_cast<std::size_t>(c);
      if (!(map.weight[k] > 0.0f) || skip.data[k]) continue;
      const double uc = map.u0 + (c + 0.5) * map.pixel, vc = map.v0 + (r + 0.5) * map.pixel;
      double quadric = 0.0;
      LocalPlane plane;
      // Too few neighbours for a plane: its own height.
      if (fit == LocalFit::kQuadric && quadric_round(map, r, c, uc, vc, skip, quadric))
        hr[c] = static_cast<float>(quadric);
      else
        hr[c] = plane_round(map, r, c, uc, vc, 0.0, skip, false, plane) ? static_cast<float>(plane.height)
                                                                        : map.w[k];
    }
  }
  return h;
}

// Pixels (CV_8U, 255) whose mean point stands out of the plane through their 8
// neighbours' mean points (less one far off the others' plane: a thrown sample's needle
// triangles pull two neighbouring pixels, and each would tilt the other's plane) by more
// than `sigmas` robust sigmas of that residual over zone, and by more than 3 times the
// neighbours' own rms about the plane. One thrown sample (a flying pixel) moves its
// pixel's mean point by up to millimetres, and near a design feature the deviation's
// spike test (deviation.h) misses it, since there the reference does not follow the
// surface; a defect lifts its pixel's neighbours with it, and a line's curvature bends
// them about the plane as much as it bends the pixel.
cv::Mat thrown_pixels(const HeightMap& map, const cv::Mat& zone, double sigmas) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  cv::Mat off(map.rows, map.cols, CV_32F, cv::Scalar(nan)), rms(map.rows, map.cols, CV_32F, cv::Scalar(nan));
#pragma omp parallel for schedule(static)
  for (int r = 0; r < map.rows; ++r)
    for (int c = 0; c < map.cols; ++c) {
      const std::size_t k =
          static_cast<std::size_t>(r) * static_cast<std::size_t>(map.cols) + static_cast<std::size_t>(c);
      LocalPlane plane;
      if (!(map.weight[k] > 0.0f) ||
          !plane_round(map, r, c, map.u[k], map.v[k], map.w[k], cv::Mat(), true, plane, true) ||
          plane.points < 4)
        continue;
      off.at<float>(r, c) = static_cast<float>(-plane.height);
      rms.at<float>(r, c) = static_cast<float>(plane.rms);
    }
  const auto limit = static_cast<float>(sigmas * sampled_robust_sigma(off, zone));
  cv::Mat thrown(map.rows, map.cols, CV_8U, cv::Scalar(0));
  for (int k = 0; k < map.rows * map.cols; ++k) {
    const float e = std::abs(off.ptr<float>()[k]);
    if (e > limit && e > 3.0f * rms.ptr<float>()[k]) thrown.data[k] = 255;  // NaN: false
  }
  return thrown;
}

// The flank samples' distances from the pixel along the line (pixels, one flank).
std::vector<double> flank_offsets(double pixel) {
  const double step = std::max(kFlankStep, pixel);
  std::vector<double> offsets;
  for (double s = kFlankNear; s <= kFlankFar + 1e-9; s += step) offsets.push_back(s / pixel);
  return offsets;
}

// The noise of m (CV_32F) along the feature through each pixel that has a direction
// (angle, NaN: none): the robust sigma of m at the flank samples (NaN where under half of
// them are seen). On a line's steep flank the heights' small errors repeat along the line
// with the pixel grid's phase; this is how large they are there.
cv::Mat noise_along(const cv::Mat& m, const cv::Mat& angle, double pixel) {
  const std::vector<double> offsets = flank_offsets(pixel);
  cv::Mat out(m.rows, m.cols, CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
#pragma omp parallel
  {
    std::vector<double> v;
#pragma omp for schedule(dynamic, 8)
    for (int r = 0; r < m.rows; ++r)
      for (int c = 0; c < m.cols; ++c) {
        const float a = angle.at<float>(r, c);
        if (!std::isfinite(a)) continue;
        v.clear();
        const double ca = std::cos(a), sa = std::sin(a);
        for (const double s : offsets)
          for (const double sign : {1.0, -1.0})
            if (const float x = sample(m, r + sign * s * sa, c + sign * s * ca); std::isfinite(x))
              v.push_back(std::abs(x));
        if (v.size() >= offsets.size()) out.at<float>(r, c) = static_cast<float>(robust_sigma(v));
      }
  }
  return out;
}

// The heights' gradient (Sobel, CV_32F) less its mean over kSlopeSigma: the panel's own
// slope would otherwise outweigh a shallow line. Only gradients whose 3 x 3
// neighbourhood is all surface count: an empty pixel's height is no height at all.
struct Gradient {
  cv::Mat gx, gy;
};
Gradient gradient_less_panel_slope(const cv::Mat& height, double pixel) {
  cv::Mat h0 = height.clone(), seen = (height == height), whole;
  cv::patchNaNs(h0, 0.0);
  cv::erode(seen, whole, cv::Mat());
  Gradient g;
  cv::Mat mx, my, weight, wsum;
  cv::Sobel(h0, g.gx, CV_32F, 1, 0, 3);
  cv::Sobel(h0, g.gy, CV_32F, 0, 1, 3);
  whole.convertTo(weight, CV_32F, 1.0 / 255.0);
  g.gx = g.gx.mul(weight), g.gy = g.gy.mul(weight);
  const cv::Size any(0, 0);
  cv::GaussianBlur(weight, wsum, any, kSlopeSigma / pixel);
  cv::GaussianBlur(g.gx, mx, any, kSlopeSigma / pixel);
  cv::GaussianBlur(g.gy, my, any, kSlopeSigma / pixel);
  wsum = cv::max(wsum, 1e-3f);
  g.gx -= mx.mul(weight) / wsum, g.gy -= my.mul(weight) / wsum;
  return g;
}

// Walls (CV_8U): a handle's sides and ends, steeper than any character line's flank,
// grown over their rounded rims. (A Sobel reads 8 pixels x the slope.)
cv::Mat walls_of(const Gradient& g, double pixel) {
  cv::Mat slope, wall;
  cv::magnitude(g.gx, g.gy, slope);
  cv::compare(slope, kWallSlope * 8.0 * pixel, wall, cv::CMP_GT);
  const int wall_reach = std::max(1, static_cast<int>(std::lround(kWallReach / pixel)));
  cv::dilate(wall, wall,
             cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * wall_reach + 1, 2 * wall_reach + 1)));
  return wall;
}

// The structure tensor of g over a Gaussian of kTensorSigma. The gradients of the pixels
// set in undirecting (CV_8U, may be empty), and those a Sobel takes them into, have no
// say round them; their own tensor is still their neighbourhood's.
struct Tensor {
  cv::Mat xx, yy, xy;
  // The feature's direction at (r, c): across the dominant gradient, where that is
  // clearly one direction (false: no line to take out).
  bool direction(int r, int c, double& a) const {
    const float jxx = xx.at<float>(r, c), jyy = yy.at<float>(r, c), jxy = xy.at<float>(r, c);
    const float tr = jxx + jyy;
    const float aniso = std::sqrt((jxx - jyy) * (jxx - jyy) + 4 * jxy * jxy);
    if (!(tr > 0.0f && aniso >= kCoherence * tr)) return false;
    a = 0.5 * std::atan2(2.0 * jxy, static_cast<double>(jxx - jyy)) + 0.5 * std::numbers::pi;
    return true;
  }
};
Tensor structure_tensor(const Gradient& g, double pixel, const cv::Mat& undirecting) {
  const double sg = kTensorSigma / pixel;
  const auto blurred = [sg](const cv::Mat& dx, const cv::Mat& dy) {
    Tensor t{dx.mul(dx), dy.mul(dy), dx.mul(dy)};
    for (cv::Mat* m : {&t.xx, &t.yy, &t.xy}) cv::GaussianBlur(*m, *m, cv::Size(0, 0), sg);
    return t;
  };
  Tensor t = blurred(g.gx, g.gy);
  if (undirecting.empty() || cv::countNonZero(undirecting) == 0) return t;
  cv::Mat gone, ux = g.gx.clone(), uy = g.gy.clone();
  cv::dilate(undirecting, gone, cv::Mat());
  ux.setTo(0.0f, gone), uy.setTo(0.0f, gone);
  const Tensor k = blurred(ux, uy);
  const cv::Mat others = ~undirecting;
  k.xx.copyTo(t.xx, others), k.yy.copyTo(t.yy, others), k.xy.copyTo(t.xy, others);
  return t;
}

// Profiles through one pixel along any direction (profile_at), with their buffers.
class ProfileSearch {
 public:
  ProfileSearch(const cv::Mat& flank, double pixel)
      : flank_(flank),
        offsets_(flank_offsets(pixel)),
        pixel_(pixel),
        need_(static_cast<int>(std::ceil(kFlankFull * static_cast<double>(offsets_.size())))) {
    xs_.reserve(2 * offsets_.size());
  }
  // The better of best and the profile along a (best_a set to a when it is).
  void try_angle(int r, int c, double a, Profile& best, double& best_a) {
    Profile f;
    if (profile_at(flank_, r, c, a, offsets_, pixel_, need_, xs_, residual_, scratch_, f) &&
        f.spread < best.spread)
      best = f, best_a = a;
  }
  // Halving steps round best_a, from 0.05 rad down to a quarter degree, to the direction
  // along which the profile fits best.
  void refine(int r, int c, Profile& best, double& best_a) {
    for (double da = 0.05; da > 0.004; da /= 2) {
      const double a0 = best_a;
      for (const double a : {a0 - da, a0 + da}) try_angle(r, c, a, best, best_a);
    }
  }

 private:
  const cv::Mat& flank_;
  std::vector<double> offsets_;
  double pixel_;
  int need_;
  std::vector<FlankSample> xs_;
  std::vector<float> residual_, scratch_;
};

}  // namespace

AlongFeature along_feature_residual(const HeightMap& map, const cv::Mat& height, const cv::Mat& steer,
                                    const cv::Mat& dev, const cv::Mat& zone, const cv::Mat& blocked,
                                    const cv::Mat& undirecting) {
  const int rows = dev.rows, cols = dev.cols;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const Gradient g = gradient_less_panel_slope(steer, map.pixel);
  AlongFeature out{cv::Mat(rows, cols, CV_32F, cv::Scalar(nan)), cv::Mat(rows, cols, CV_32F, cv::Scalar(nan)),
                   cv::Mat(rows, cols, CV_32F, cv::Scalar(nan)), walls_of(g, map.pixel)};
  // The heights the profiles are fitted to: walls are no skin, neither looked at nor in
  // any profile.
  cv::Mat flank = height.clone();
  flank.setTo(nan, blocked);
  flank.setTo(nan, out.wall);
  const Tensor tensor = structure_tensor(g, map.pixel, undirecting);
#pragma omp parallel
  {
    ProfileSearch search(flank, map.pixel);
#pragma omp for schedule(dynamic, 8)
    for (int r = 0; r < rows; ++r) {
      const std::uint8_t* zr = zone.ptr<std::uint8_t>(r);
      for (int c = 0; c < cols; ++c) {
        const float here = dev.at<float>(r, c), h = height.at<float>(r, c);
        if (!zr[c] || !std::isfinite(h) || out.wall.at<std::uint8_t>(r, c)) continue;
        Profile best{0.0f, std::numeric_limits<float>::infinity()};
        double best_a = 0.0;
        if (tensor.direction(r, c, best_a)) {
          search.try_angle(r, c, best_a, best, best_a);
        } else if (std::isfinite(here)) {
          // No direction dominates (a rim beside a wall, a flat stretch): the direction,
          // of eight, along which the surface's profile fits best. Not near the border,
          // whose rolled edge bends every profile that reaches it.
          for (int i = 0; i < 8; ++i) search.try_angle(r, c, i * std::numbers::pi / 8.0, best, best_a);
          if (!std::isfinite(best.spread)) {
            out.residual.at<float>(r, c) = here;
            out.uncertainty.at<float>(r, c) = 0.0f;
            continue;
          }
        }
        search.refine(r, c, best, best_a);
        if (!std::isfinite(best.spread)) continue;
        const std::size_t k =
            static_cast<std::size_t>(r) * static_cast<std::size_t>(cols) + static_cast<std::size_t>(c);
        out.residual.at<float>(r, c) = (h - best.at_pixel) * map.cos_tilt[k];
        out.angle.at<float>(r, c) = static_cast<float>(best_a);
        out.uncertainty.at<float>(r, c) = std::max(kSpreadSigmas * best.spread, best.gap) * map.cos_tilt[k];
      }
    }
  }
  return out;
}

namespace {

// The residual's candidate pixels (cand: CV_8U, 255 where some detection scale's mean of
// it passes its threshold), the finest scale's mean, and that scale's noise.
struct ResidualCandidates {
  cv::Mat cand, finest;
  double finest_sigma = 0.0;
};
ResidualCandidates residual_candidates(const AlongFeature& along, const AlongFeatureScene& s,
                                       const cv::Mat& zone, const cv::Mat& blocked, const DetectConfig& cfg) {
  const int rows = s.map.rows, cols = s.map.cols;
  // The detection scales' means of the residual and their thresholds (deviation.h).
  cv::Mat values(rows, cols, CV_32F), weights(rows, cols, CV_32F), doubts(rows, cols, CV_32F);
  for (int k = 0; k < rows * cols; ++k) {
    const float v = along.residual.ptr<float>()[k];
    // Off the profile by more than a hole is deep: a feature's own shape (a handle's end,
    // its top), never a dent's.
    const bool ok = std::abs(v) <= cfg.hole_depth && !s.excluded.data[k];  // NaN: false
    values.ptr<float>()[k] = ok ? v : 0.0f;
    weights.ptr<float>()[k] = ok ? 1.0f : 0.0f;
    doubts.ptr<float>()[k] = ok ? along.uncertainty.ptr<float>()[k] : 0.0f;
  }
  ResidualCandidates out{cv::Mat(rows, cols, CV_8U, cv::Scalar(0)), cv::Mat(), s.sigma3};
  cv::Mat local;  // the finest scale's noise along the feature
  for (std::size_t i = 0; i < s.scales.size(); ++i) {
    cv::Mat mean, doubt;
    const int k = s.scales[i];
    box_mean(values, weights, k, 0.3f * static_cast<float>(k * k), mean);
    // A mean carries the profile errors of every pixel in it: they are shared along the
    // line, so they do not average out, and a mean beside an uncertain stretch is as
    // uncertain as the share of it that it takes in.
    box_mean(doubts, weights, k, 0.3f * static_cast<float>(k * k), doubt);
    // The residual's own noise at this scale: the profile's error is shared by
    // neighbouring pixels (their flanks overlap), so it does not average out as the
    // deviation's noise does.
    const double sigma = std::max(s.scale_sigma[i], sampled_robust_sigma(mean, zone));
    const auto thr = static_cast<float>(std::max(cfg.detection_sigma * sigma, 0.5 * cfg.min_height));
    if (i == 0) {
      cv::Mat seen = mean.clone();
      seen.setTo(std::numeric_limits<float>::quiet_NaN(), blocked);
      local = noise_along(seen, along.angle, s.map.pixel);
    }
    const auto local_sigmas = static_cast<float>(cfg.detection_sigma);
    for (int q = 0; q < rows * cols; ++q) {
      const float m = mean.ptr<float>()[q];
      // Where the flanks spread or disagree (the steep part of a line that bends, a
      // handle's end) the profile is uncertain by as much; and where the residual itself
      // varies along the line, by as much as it does.
      const float lq = local.ptr<float>()[q];
      const float t = std::max({thr, doubt.ptr<float>()[q], std::isfinite(lq) ? local_sigmas * lq : 0.0f});
      if (std::abs(m) > t && weights.ptr<float>()[q] > 0.0f && zone.data[q])
        out.cand.data[q] = 255;  // NaN: false
    }
    if (i == 0) out.finest = mean, out.finest_sigma = std::max(s.sigma3, sigma);
  }
  return out;
}

// The candidates' connected pieces that have the shape and height of a defect, away
// from defects already reported, as findings with their pixels. peaked (CV_8U, may be
// null) gets the pixels of every piece whose peak stands out, however narrow the part
// round its peak is.
std::vector<Finding> findings_of(const ResidualCandidates& rc, const AlongFeatureScene& s,
                                 const cv::Mat& wall_foot, const DetectConfig& cfg,
                                 std::vector<std::vector<std::int32_t>>& pixels, cv::Mat* peaked = nullptr) {
  const HeightMap& map = s.map;
  const int rows = map.rows, cols = map.cols;
  const cv::Mat& finest = rc.finest;
  std::vector<Finding> out;
  cv::Mat lab;
  const int n = cv::connectedComponents(rc.cand, lab, 8, CV_32S);
  std::vector<std::vector<std::int32_t>> comps(static_cast<std::size_t>(n));
  for (int q = 0; q < rows * cols; ++q)
    if (const int l = lab.ptr<int>()[q]; l > 0) comps[static_cast<std::size_t>(l)].push_back(q);
  for (int l = 1; l < n; ++l) {
    std::vector<std::int32_t>& px = comps[static_cast<std::size_t>(l)];
    if (std::any_of(px.begin(), px.end(),
                    [&](std::int32_t q) { return s.labels[static_cast<std::size_t>(q)] >= 0; }))
      continue;
    const CandidateShape shape = shape_of(px, map, s.edge_zone);
    if (design_reason(shape, cfg) || shape.length < std::max(cfg.min_diameter, 2.5 * map.pixel)) continue;
    // Peak of the finest scale's mean; the half-height region gives centre and size.
    // Not at a wall's foot: where a wall turns (a handle's corner) the foot's own
    // rounding stands out of a profile along the rim, which runs through flat flanks.
    float peak = 0.0f;
    for (const std::int32_t q : px) {
      const float m = finest.ptr<float>()[q];
      if (std::isfinite(m) && std::abs(m) > std::abs(peak) && !wall_foot.data[q]) peak = m;
    }
    const double snr = std::abs(peak) / std::max(rc.finest_sigma, 1e-9);
    if (std::abs(peak) < cfg.min_height || snr < cfg.detection_sigma) continue;
    if (peaked)
      for (const std::int32_t q : px) peaked->data[q] = 255;
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
    d.area = disc_area(d.diameter);
    d.score = score_of(snr, cfg.detection_sigma);
    d.defect_class = peak < 0 ? protocol::DefectClass::kDent : protocol::DefectClass::kBump;
    f.reason = peak < 0 ? "depression beside or on a design feature (out of its profile along it)"
                        : "protrusion beside or on a design feature (out of its profile along it)";
    out.push_back(std::move(f));
    pixels.push_back(std::move(px));
  }
  return out;
}

// The findings, those within kJoinGap of a stronger one of the same sign (rim to rim,
// at their measured diameters) merged into it: a defect across a line's flank is cut
// where its profile is least sure, the steep middle, and its halves would read as two.
// The merged finding keeps the stronger one's height and normal; its centre is the
// pieces' area-weighted mean and its diameter spans both. pixels are kept in step.
// (order_findings joins splits too, but only a centre within half the larger diameter:
// the halves either side of a flank lie further apart.)
std::vector<Finding> one_per_defect(std::vector<Finding> found,
                                    std::vector<std::vector<std::int32_t>>& pixels) {
  std::vector<std::size_t> order(found.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return std::abs(found[a].defect.height) > std::abs(found[b].defect.height);
  });
  std::vector<std::size_t> kept;  // indices into found, strongest first
  for (const std::size_t i : order) {
    const protocol::Defect& weak = found[i].defect;
    const auto into = std::find_if(kept.begin(), kept.end(), [&](std::size_t k) {
      const protocol::Defect& strong = found[k].defect;
      return strong.height * weak.height > 0.0 &&
             (strong.position - weak.position).norm() < 0.5 * (strong.diameter + weak.diameter) + kJoinGap;
    });
    if (into == kept.end()) {
      kept.push_back(i);
      continue;
    }
    protocol::Defect& strong = found[*into].defect;
    const double a = strong.area, b = weak.area;
    const double span = (strong.position - weak.position).norm() + 0.5 * (strong.diameter + weak.diameter);
    strong.position = (a * strong.position + b * weak.position) / (a + b);
    strong.diameter = std::max(strong.diameter, span);
    strong.area = disc_area(strong.diameter);
    found[*into].pixels += found[i].pixels;
    pixels[*into].insert(pixels[*into].end(), pixels[i].begin(), pixels[i].end());
  }
  std::sort(kept.begin(), kept.end());
  std::vector<Finding> out;
  std::vector<std::vector<std::int32_t>> out_pixels;
  for (const std::size_t k : kept)
    out.push_back(std::move(found[k])), out_pixels.push_back(std::move(pixels[k]));
  pixels = std::move(out_pixels);
  return out;
}

}  // namespace

std::vector<Finding> defects_along_features(const AlongFeatureScene& s, const DetectConfig& cfg,
                                            std::vector<std::vector<std::int32_t>>& pixels) {
  const HeightMap& map = s.map;
  if (cv::countNonZero(s.design) == 0) return {};
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
  // A defect in a pixel's flanks lifts or lowers its profile and leaves a ghost of the
  // other sign 13-45 mm along the line each side of it. So the first pass's findings
  // leave the flanks of the second.
  // Where no feature has a direction the deviation itself is searched again (a defect
  // the search took for part of a design feature), but not near the border, whose own
  // band (and a line running into it) the search has already judged.
  cv::Mat plain = s.dev.clone(), near_border;
  const int border_reach = std::max(1, static_cast<int>(std::lround(kPlainEdgeReach / map.pixel)));
  cv::dilate(
      s.edge_zone, near_border,
      cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * border_reach + 1, 2 * border_reach + 1)));
  plain.setTo(std::numeric_limits<float>::quiet_NaN(), near_border);
  // The profiles are fitted to the quadrics' heights. The direction is read from the
  // planes', which are less noisy (a 3 x 3 plane's centre carries 1/9 of a point's
  // variance, a quadric's 5/9): from the quadrics', a crease's direction beside a deep
  // dent turned enough to leave a false bump beside the dent.
  const cv::Mat skip = s.excluded | thrown_pixels(map, zone, cfg.detection_sigma);
  const cv::Mat height = heights_of(map, skip, LocalFit::kQuadric),
                steer = heights_of(map, skip, LocalFit::kPlane);
  AlongFeature along = along_feature_residual(map, height, steer, plain, zone, near_edge, cv::Mat());
  cv::Mat wall_foot;
  const int foot_reach = std::max(1, static_cast<int>(std::lround(kWallFoot / map.pixel)));
  cv::dilate(along.wall, wall_foot,
             cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * foot_reach + 1, 2 * foot_reach + 1)));
  // What the first run found leaves the flanks of the second, and so do its pieces too
  // narrow to report whose peak stands out: a wide defect centred on a line's flank
  // leaves a ghost of the other sign in the profiles whose flanks cross it, the ghosts
  // raise the noise along the line (noise_along) over the defect's own residual, and
  // only its two sides stand out, as narrow pieces.
  cv::Mat found(map.rows, map.cols, CV_8U, cv::Scalar(0)), peaked = found.clone();
  std::vector<std::vector<std::int32_t>> first_px;
  findings_of(residual_candidates(along, s, zone, near_edge, cfg), s, wall_foot, cfg, first_px, &peaked);
  for (const auto& px : first_px)
    for (const std::int32_t q : px) found.data[q] = 255;
  const cv::Mat grow = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5));
  cv::dilate(found, found, grow);
  cv::dilate(peaked, peaked, grow);
  const cv::Mat blocked = peaked | near_edge;
  // Only pixels with such a piece within a flank's reach see their flanks change. A
  // finding's gradients turn the direction of the feature beside it as well, so they
  // are left out of it (not a narrow piece's: many are a feature's own remnants, and
  // without them a crease's direction beside a deep dent turned and left a false bump).
  const int flank_reach = static_cast<int>(std::ceil(kFlankFar / map.pixel));
  cv::Mat again;
  cv::dilate(
      peaked, again,
      cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * flank_reach + 1, 2 * flank_reach + 1)));
  again &= zone;
  if (cv::countNonZero(again) > 0) {
    const AlongFeature second = along_feature_residual(map, height, steer, plain, again, blocked, found);
    second.residual.copyTo(along.residual, again);
    second.uncertainty.copyTo(along.uncertainty, again);
    second.angle.copyTo(along.angle, again);
  }
  return one_per_defect(
      findings_of(residual_candidates(along, s, zone, blocked, cfg), s, wall_foot, cfg, pixels), pixels);
}

}  // namespace dentmark::detect
