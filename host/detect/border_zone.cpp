#include "border_zone.h"

#include <cmath>
#include <cstdint>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "components.h"
#include "dilate.h"

namespace dentmark::detect {

cv::Mat border_zone(const HeightMap& map) {
  const double h = map.pixel;
  const auto n = static_cast<std::int64_t>(map.size());
  const float* weight = map.weight.data();
  cv::Mat unseen(map.rows, map.cols, CV_8U);  // (a mask per pixel: both threads)
  std::uint8_t* up = unseen.ptr<std::uint8_t>();
#pragma omp parallel for schedule(static)
  for (std::int64_t k = 0; k < n; ++k) up[k] = weight[k] <= 0.0f ? 255 : 0;
  const Components empty = label_components(unseen, 4);
  const double big = std::pow(0.01 / h, 2);
  std::vector<std::uint8_t> outside(static_cast<std::size_t>(empty.count), 0);
  for (std::size_t i = 1; i < outside.size(); ++i)
    outside[i] = empty.area[i] >= big || empty.touches_border[i];
  cv::Mat out_mask(map.rows, map.cols, CV_8U);
  const int* lp = empty.labels.ptr<int>();  // 0 on occupied pixels, which outside[0] = 0 leaves out
  std::uint8_t* op = out_mask.ptr<std::uint8_t>();
#pragma omp parallel for schedule(static)
  for (std::int64_t k = 0; k < n; ++k) op[k] = outside[static_cast<std::size_t>(lp[k])] ? 255 : 0;
  const int rad = std::max(2, static_cast<int>(std::lround(0.003 / h)));
  cv::Mat zone;
  dilate_in_strips(out_mask, zone, cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * rad + 1, 2 * rad + 1}));
  std::uint8_t* zp = zone.ptr<std::uint8_t>();
#pragma omp parallel for schedule(static)
  for (std::int64_t k = 0; k < n; ++k)
    if (!(weight[k] > 0.0f)) zp[k] = 0;
  return zone;
}

}  // namespace dentmark::detect
