#include "dentmark/firmware/track/pyramid_lk.h"

#include <algorithm>
#include <cmath>
#include <opencv2/video/tracking.hpp>

namespace dentmark::track {

ImagePyramid::ImagePyramid(const cv::Mat& grey, const LkOptions& o, cv::Rect region) : image_(grey) {
  const cv::Rect all(0, 0, grey.cols, grey.rows);
  const int align = 1 << o.levels;
  if (region.area() <= 0) region = all;
  const int x0 = std::max(0, region.x) / align * align, y0 = std::max(0, region.y) / align * align;
  region_ = cv::Rect(cv::Point(x0, y0), region.br()) & all;
  if (region_.area() <= 0) region_ = all;
  // Padded levels (no derivatives: LK computes them on the small windows it uses).
  cv::buildOpticalFlowPyramid(grey(region_), levels_, cv::Size(o.window, o.window), o.levels, false,
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
  // One window of every level covering start and guess, inside both pyramids' regions;
  // its origin is a multiple of 2^levels so that the windows are exact halvings.
  const int align = 1 << levels;
  const int reach = o.window * align / 2 + o.window;
  const cv::Rect common = from.region() & to.region();
  int x0 = std::max(common.x, static_cast<int>(std::floor(std::min(p_from.x, g.x))) - reach);
  int y0 = std::max(common.y, static_cast<int>(std::floor(std::min(p_from.y, g.y))) - reach);
  const int x1 =
      std::min(common.x + common.width, static_cast<int>(std::ceil(std::max(p_from.x, g.x))) + reach);
  const int y1 =
      std::min(common.y + common.height, static_cast<int>(std::ceil(std::max(p_from.y, g.y))) + reach);
  x0 = (x0 + align - 1) / align * align;
  y0 = (y0 + align - 1) / align * align;
  if (p_from.x < x0 || p_from.y < y0 || g.x < x0 || g.y < y0 || p_from.x >= x1 || g.x >= x1 ||
      p_from.y >= y1 || g.y >= y1)
    return std::nullopt;
  std::vector<cv::Mat> a, b;
  for (int l = 0; l <= levels; ++l) {
    const auto& la = from.levels()[static_cast<std::size_t>(l)];
    const auto& lb = to.levels()[static_cast<std::size_t>(l)];
    const int ax = (x0 - from.region().x) >> l, ay = (y0 - from.region().y) >> l;
    const int bx = (x0 - to.region().x) >> l, by = (y0 - to.region().y) >> l;
    const int w = std::min({(x1 - x0) >> l, la.cols - ax, lb.cols - bx});
    const int h = std::min({(y1 - y0) >> l, la.rows - ay, lb.rows - by});
    if (w < 8 || h < 8) break;
    a.push_back(la(cv::Rect(ax, ay, w, h)));
    b.push_back(lb(cv::Rect(bx, by, w, h)));
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
