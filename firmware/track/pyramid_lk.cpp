#include "dentmark/firmware/track/pyramid_lk.h"

#include <algorithm>
#include <cmath>
#include <opencv2/video/tracking.hpp>

namespace dentmark::track {

ImagePyramid::ImagePyramid(const cv::Mat& grey, const LkOptions& o) {
  // Padded levels (no derivatives: LK computes them on the small windows it uses).
  cv::buildOpticalFlowPyramid(grey, levels_, cv::Size(o.window, o.window), o.levels, false,
                              cv::BORDER_REFLECT_101, cv::BORDER_CONSTANT, false);
}

std::optional<cv::Point2f> track_lk(const ImagePyramid& from, const ImagePyramid& to,
                                    const cv::Point2f& p_from, const cv::Point2f& guess, const LkOptions& o) {
  if (from.empty() || to.empty() || from.size() != to.size()) return std::nullopt;
  const int levels = static_cast<int>(std::min(from.levels().size(), to.levels().size())) - 1;
  const cv::Size size = from.size();
  auto inside = [&](const cv::Point2f& p) {
    return p.x >= 0 && p.y >= 0 && p.x <= size.width - 1 && p.y <= size.height - 1;
  };
  if (!inside(p_from) || !std::isfinite(guess.x) || !std::isfinite(guess.y)) return std::nullopt;
  const cv::Point2f g = inside(guess) ? guess : p_from;
  // One window of every level covering start and guess; its origin is a multiple of
  // 2^levels so that the windows are exact halvings of each other.
  const int align = 1 << levels;
  const int reach = o.window * align / 2 + 2 * o.window;
  int x0 = static_cast<int>(std::floor(std::min(p_from.x, g.x))) - reach;
  int y0 = static_cast<int>(std::floor(std::min(p_from.y, g.y))) - reach;
  const int x1 = static_cast<int>(std::ceil(std::max(p_from.x, g.x))) + reach;
  const int y1 = static_cast<int>(std::ceil(std::max(p_from.y, g.y))) + reach;
  x0 = std::max(0, x0 / align * align);
  y0 = std::max(0, y0 / align * align);
  std::vector<cv::Mat> a, b;
  for (int l = 0; l <= levels; ++l) {
    const cv::Size ls = from.levels()[static_cast<std::size_t>(l)].size();
    const int lx0 = x0 >> l, ly0 = y0 >> l;
    const int lx1 = std::min(ls.width, (x1 + (1 << l) - 1) >> l),
              ly1 = std::min(ls.height, (y1 + (1 << l) - 1) >> l);
    if (lx1 - lx0 < 8 || ly1 - ly0 < 8) break;
    const cv::Rect r(lx0, ly0, lx1 - lx0, ly1 - ly0);
    a.push_back(from.levels()[static_cast<std::size_t>(l)](r));
    b.push_back(to.levels()[static_cast<std::size_t>(l)](r));
  }
  if (a.empty()) return std::nullopt;
  const cv::Point2f off(static_cast<float>(x0), static_cast<float>(y0));
  std::vector<cv::Point2f> p0{p_from - off}, p1{g - off};
  std::vector<uchar> status;
  std::vector<float> err;
  cv::calcOpticalFlowPyrLK(
      a, b, p0, p1, status, err, cv::Size(o.window, o.window), static_cast<int>(a.size()) - 1,
      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, o.iterations, o.epsilon),
      cv::OPTFLOW_USE_INITIAL_FLOW);
  if (status.empty() || !status[0]) return std::nullopt;
  const cv::Point2f p = p1[0] + off;
  if (!std::isfinite(p.x) || !std::isfinite(p.y) || !inside(p)) return std::nullopt;
  return p;
}

}  // namespace dentmark::track
