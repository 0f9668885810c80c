#include "dentmark/firmware/track/template_align.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace dentmark::track {
namespace {

// The size x size patch centred at c, bicubic (Keys, a = −0.5). Every sample shares
// one sub-pixel phase, so this is a separable 4-tap filter of the pixel grid. Bilinear
// sampling would smooth by a phase-dependent amount and bias alignment of sharp images
// (and cv::remap quantises positions to 1/32 px).
void sample(const cv::Mat& grey, const cv::Point2d& c, int size, cv::Mat& out) {
  const double h = 0.5 * (size - 1);
  const double sx = c.x - h, sy = c.y - h;
  const int x0 = static_cast<int>(std::floor(sx)), y0 = static_cast<int>(std::floor(sy));
  const double tx = sx - x0, ty = sy - y0;
  auto weights = [](double t) {
    return std::array<double, 4>{-0.5 * t * t * t + t * t - 0.5 * t, 1.5 * t * t * t - 2.5 * t * t + 1.0,
                                 -1.5 * t * t * t + 2.0 * t * t + 0.5 * t, 0.5 * t * t * t - 0.5 * t * t};
  };
  const auto wx = weights(tx), wy = weights(ty);
  cv::Mat1f rows(size + 3, size);
  for (int y = 0; y < size + 3; ++y) {
    const int yy = std::clamp(y0 - 1 + y, 0, grey.rows - 1);
    const uchar* src = grey.ptr<uchar>(yy);
    for (int x = 0; x < size; ++x) {
      double v = 0.0;
      for (int k = 0; k < 4; ++k)
        v += wx[static_cast<std::size_t>(k)] * src[std::clamp(x0 - 1 + x + k, 0, grey.cols - 1)];
      rows(y, x) = static_cast<float>(v);
    }
  }
  out.create(size, size, CV_32F);
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      double v = 0.0;
      for (int k = 0; k < 4; ++k) v += wy[static_cast<std::size_t>(k)] * rows(y + k, x);
      out.at<float>(y, x) = static_cast<float>(v);
    }
}

}  // namespace

GridTemplate grid_template(const cv::Mat& grey, const cv::Point2f& p, int half) {
  GridTemplate t;
  const cv::Point c(cvRound(p.x), cvRound(p.y));
  t.offset = p - cv::Point2f(static_cast<float>(c.x), static_cast<float>(c.y));
  const cv::Rect r(c.x - half, c.y - half, 2 * half + 1, 2 * half + 1);
  if ((r & cv::Rect(0, 0, grey.cols, grey.rows)) != r) return t;
  grey(r).convertTo(t.patch, CV_32F);
  return t;
}

cv::Mat affine_patch(const cv::Mat& grey, const cv::Point2d& centre, const cv::Matx22d& a, int half) {
  const int n = 2 * half + 1;
  // The corners of the sampled area must keep the 4-tap support inside the image.
  for (int sy : {-1, 1})
    for (int sx : {-1, 1}) {
      const cv::Vec2d q = a * cv::Vec2d(sx * half, sy * half);
      const double x = centre.x + q[0], y = centre.y + q[1];
      if (!(x >= 1 && y >= 1 && x < grey.cols - 3 && y < grey.rows - 3)) return {};
    }
  auto weights = [](double t) {
    return std::array<double, 4>{-0.5 * t * t * t + t * t - 0.5 * t, 1.5 * t * t * t - 2.5 * t * t + 1.0,
                                 -1.5 * t * t * t + 2.0 * t * t + 0.5 * t, 0.5 * t * t * t - 0.5 * t * t};
  };
  cv::Mat out(n, n, CV_32F);
  for (int v = -half; v <= half; ++v)
    for (int u = -half; u <= half; ++u) {
      const double x = centre.x + a(0, 0) * u + a(0, 1) * v, y = centre.y + a(1, 0) * u + a(1, 1) * v;
      const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
      const auto wx = weights(x - x0), wy = weights(y - y0);
      double value = 0.0;
      for (int j = 0; j < 4; ++j) {
        const uchar* row = grey.ptr<uchar>(y0 - 1 + j);
        double r = 0.0;
        for (int i = 0; i < 4; ++i) r += wx[static_cast<std::size_t>(i)] * row[x0 - 1 + i];
        value += wy[static_cast<std::size_t>(j)] * r;
      }
      out.at<float>(v + half, u + half) = static_cast<float>(value);
    }
  return out;
}

std::optional<Alignment> align_template(const cv::Mat& grey, const cv::Mat& templ, const cv::Point2f& start,
                                        const AlignOptions& o) {
  const int n = templ.cols;
  const int half = n / 2;
  if (templ.rows != n || n % 2 == 0 || templ.type() != CV_32F) return std::nullopt;
  cv::Point2d p(start.x, start.y);
  double gain = 1.0, bias = 0.0;
  cv::Mat big;
  // Photometric start: match the patch's mean and spread.
  auto inside = [&](const cv::Point2d& q) {
    return q.x > half + 2 && q.y > half + 2 && q.x < grey.cols - half - 3 && q.y < grey.rows - half - 3;
  };
  cv::Scalar tm, ts;
  cv::meanStdDev(templ, tm, ts);
  if (ts[0] < 1e-3) return std::nullopt;
  bool converged = false;
  for (int it = 0; it < o.iterations; ++it) {
    if (!inside(p)) return std::nullopt;
    // The image around p with a one-pixel rim for central differences.
    sample(grey, p, n + 2, big);
    if (it == 0) {
      cv::Scalar im, is;
      cv::meanStdDev(big(cv::Rect(1, 1, n, n)), im, is);
      gain = is[0] > 1e-3 ? is[0] / ts[0] : 1.0;
      bias = im[0] - gain * tm[0];
    }
    Eigen::Matrix4d h = Eigen::Matrix4d::Zero();
    Eigen::Vector4d g = Eigen::Vector4d::Zero();
    for (int y = 0; y < n; ++y) {
      const float* r0 = big.ptr<float>(y);
      const float* r1 = big.ptr<float>(y + 1);
      const float* r2 = big.ptr<float>(y + 2);
      const float* t = templ.ptr<float>(y);
      for (int x = 0; x < n; ++x) {
        const double ix = 0.5 * (r1[x + 2] - r1[x]);
        const double iy = 0.5 * (r2[x + 1] - r0[x + 1]);
        const double e = r1[x + 1] - (gain * t[x] + bias);
        const Eigen::Vector4d j(ix, iy, -t[x], -1.0);
        h.selfadjointView<Eigen::Upper>().rankUpdate(j);
        g += j * e;
      }
    }
    const Eigen::Matrix4d hf = h.selfadjointView<Eigen::Upper>();
    const Eigen::Vector4d step = hf.ldlt().solve(-g);
    if (!step.allFinite()) return std::nullopt;
    p.x += step(0);
    p.y += step(1);
    gain += step(2);
    bias += step(3);
    if (std::hypot(p.x - start.x, p.y - start.y) > o.max_shift || !(gain > 0.05)) return std::nullopt;
    if (std::hypot(step(0), step(1)) < o.epsilon) {
      converged = true;
      break;
    }
  }
  if (!converged || !inside(p)) return std::nullopt;
  cv::Mat patch;
  sample(grey, p, n, patch);
  cv::Scalar pm, ps;
  cv::meanStdDev(patch, pm, ps);
  Alignment a;
  a.position = cv::Point2f(static_cast<float>(p.x), static_cast<float>(p.y));
  a.ncc = ps[0] > 1e-6 ? cv::mean((patch - pm[0]).mul(templ - tm[0]))[0] / (ps[0] * ts[0]) : -1.0;
  return a;
}

}  // namespace dentmark::track
