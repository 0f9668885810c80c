#include "dentmark/firmware/track/corner_refine.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "dentmark/common/nth_smallest.h"

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
  // Shi-Tomasi corners are the local maxima of the minimum eigenvalue that stand well
  // above the window's typical (edge or flat) response; the one nearest the seed wins,
  // since a neighbouring, stronger corner may be in the window too (an obtuse corner
  // responds far less than a right-angled one).
  std::vector<float> values;
  double peak_max = 0.0;
  for (int y = 0; y < roi.height; ++y)
    for (int x = 0; x < roi.width; ++x) {
      const float e = eig.at<float>(y, x);
      values.push_back(e);
      peak_max = std::max(peak_max, static_cast<double>(e));
    }
  const double floor = std::max({8.0 * median_in_place(values), 0.03 * peak_max, 1e-4});
  double best_d2 = 1e300;
  cv::Point best_p(-1, -1);
  for (int y = 1; y + 1 < roi.height; ++y)
    for (int x = 1; x + 1 < roi.width; ++x) {
      const float e = eig.at<float>(y, x);
      if (e < floor) continue;
      const double dx = roi.x + x - seed.x, dy = roi.y + y - seed.y;
      const double d2 = dx * dx + dy * dy;
      if (d2 > r * r || d2 >= best_d2) continue;
      bool is_max = true;
      for (int v = -1; v <= 1 && is_max; ++v)
        for (int u = -1; u <= 1; ++u)
          if ((u || v) && eig.at<float>(y + v, x + u) > e) is_max = false;
      if (is_max) best_d2 = d2, best_p = {roi.x + x, roi.y + y};
    }
  if (best_p.x < 0) return std::nullopt;
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
