#include "dentmark/firmware/track/corner_refine.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <vector>

namespace dentmark::track {

std::optional<cv::Point2f> subpixel_corner(const cv::Mat& grey, const cv::Point2f& start, int half_window,
                                           double max_shift) {
  const float m = static_cast<float>(half_window + 2);
  if (start.x < m || start.y < m || start.x > grey.cols - 1 - m || start.y > grey.rows - 1 - m)
    return std::nullopt;
  std::vector<cv::Point2f> pts{start};
  cv::cornerSubPix(grey, pts, cv::Size(half_window, half_window), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 40, 0.001));
  const cv::Point2f d = pts[0] - start;
  if (!std::isfinite(pts[0].x) || !std::isfinite(pts[0].y) || std::hypot(d.x, d.y) > max_shift)
    return std::nullopt;
  if (pts[0].x < m || pts[0].y < m || pts[0].x > grey.cols - 1 - m || pts[0].y > grey.rows - 1 - m)
    return std::nullopt;
  return pts[0];
}

std::optional<cv::Point2f> refine_seed(const cv::Mat& grey, const cv::Point2f& seed, const CornerOptions& o) {
  const int r = o.search_radius;
  const int margin = r + o.subpix_half_window + 4;
  const cv::Rect img_rect(0, 0, grey.cols, grey.rows);
  const cv::Rect roi =
      cv::Rect(cvRound(seed.x) - margin, cvRound(seed.y) - margin, 2 * margin + 1, 2 * margin + 1) & img_rect;
  if (roi.area() < 25) return std::nullopt;
  cv::Mat eig;
  cv::cornerMinEigenVal(grey(roi), eig, 5, 3);
  // Shi-Tomasi score, weighted towards the seed (seeds are a few pixels off, and a
  // neighbouring corner may be in the window too).
  const double sigma = 0.6 * r;
  double best = 0.0;
  cv::Point best_p(-1, -1);
  std::vector<float> values;
  for (int y = 0; y < roi.height; ++y)
    for (int x = 0; x < roi.width; ++x) {
      const double dx = roi.x + x - seed.x, dy = roi.y + y - seed.y;
      if (dx * dx + dy * dy > r * r) continue;
      const float e = eig.at<float>(y, x);
      values.push_back(e);
      const double s = e * std::exp(-(dx * dx + dy * dy) / (2 * sigma * sigma));
      if (s > best) best = s, best_p = {roi.x + x, roi.y + y};
    }
  if (best_p.x < 0 || values.empty()) return std::nullopt;
  // A distinct corner stands well above the window's typical (edge or flat) response.
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  const double median = values[values.size() / 2];
  const double peak = eig.at<float>(best_p.y - roi.y, best_p.x - roi.x);
  if (!(peak > 1e-4) || peak < 8.0 * median) return std::nullopt;
  return subpixel_corner(grey, cv::Point2f(static_cast<float>(best_p.x), static_cast<float>(best_p.y)),
                         o.subpix_half_window, r + 2.0);
}

cv::Mat patch_at(const cv::Mat& grey, const cv::Point2f& p, int half) {
  cv::Mat patch;
  cv::getRectSubPix(grey, cv::Size(2 * half + 1, 2 * half + 1), p, patch, CV_32F);
  return patch;
}

double patch_ncc(const cv::Mat& grey, const cv::Point2f& p, const cv::Mat& templ) {
  const int half = templ.cols / 2;
  if (p.x < half + 1 || p.y < half + 1 || p.x > grey.cols - half - 2 || p.y > grey.rows - half - 2)
    return -1.0;
  const cv::Mat patch = patch_at(grey, p, half);
  cv::Scalar ma, sa, mb, sb;
  cv::meanStdDev(patch, ma, sa);
  cv::meanStdDev(templ, mb, sb);
  if (sa[0] < 1e-6 || sb[0] < 1e-6) return -1.0;
  const double cov = cv::mean((patch - ma[0]).mul(templ - mb[0]))[0];
  return cov / (sa[0] * sb[0]);
}

}  // namespace dentmark::track
