#include "components.h"

#include <opencv2/imgproc.hpp>

namespace dentmark::detect {

Components label_components(const cv::Mat& mask, int connectivity) {
  Components c;
  c.count = cv::connectedComponents(mask, c.labels, connectivity, CV_32S);
  const auto labels = static_cast<std::size_t>(c.count);
  const int rows = c.labels.rows, cols = c.labels.cols;
  // Areas: each thread counts a band of rows, then the counts are added (integers: the
  // same whatever the split).
  c.area.assign(labels, 0);
#pragma omp parallel
  {
    std::vector<std::int32_t> mine(labels, 0);
#pragma omp for schedule(static) nowait
    for (int r = 0; r < rows; ++r) {
      const int* lab = c.labels.ptr<int>(r);
      for (int x = 0; x < cols; ++x) ++mine[static_cast<std::size_t>(lab[x])];
    }
#pragma omp critical
    for (std::size_t i = 0; i < labels; ++i) c.area[i] += mine[i];
  }
  c.touches_border.assign(labels, 0);
  const auto mark = [&](int r, int x) {
    c.touches_border[static_cast<std::size_t>(c.labels.at<int>(r, x))] = 1;
  };
  for (int x = 0; x < cols; ++x) mark(0, x), mark(rows - 1, x);
  for (int r = 0; r < rows; ++r) mark(r, 0), mark(r, cols - 1);
  return c;
}

}  // namespace dentmark::detect
