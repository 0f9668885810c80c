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
  cv::Mat weight(map.rows, map.cols, CV_32F, const_cast<float*>(map.weight.data()));
  const Components empty = label_components(weight <= 0.0f, 4);
  const double big = std::pow(0.01 / h, 2);
  std::vector<std::uint8_t> outside(static_cast<std::size_t>(empty.count), 0);
  for (std::size_t i = 1; i < outside.size(); ++i)
    outside[i] = empty.area[i] >= big || empty.touches_border[i];
  cv::Mat out_mask(map.rows, map.cols, CV_8U);
  const int* lp = empty.labels.ptr<int>();  // 0 on occupied pixels, which outside[0] = 0 leaves out
  std::uint8_t* op = out_mask.ptr<std::uint8_t>();
#pragma omp parallel for schedule(static)
  for (std::int64_t k = 0; k < static_cast<std::int64_t>(map.size()); ++k)
    op[k] = outside[static_cast<std::size_t>(lp[k])] ? 255 : 0;
  const int rad = std::max(2, static_cast<int>(std::lround(0.003 / h)));
  cv::Mat zone;
  dilate_in_strips(out_mask, zone, cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * rad + 1, 2 * rad + 1}));
  zone &= weight > 0.0f;
  return zone;
}

}  // namespace dentmark::detect
