#include "box_mean.h"

#include <algorithm>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <vector>

namespace dentmark::detect {

// Both sums in one pass of running sums: column sums over the window's rows, moved down
// a row at a time, then row sums over the window's columns. Bands of rows go to the
// threads; sums are kept in double, so running them costs no precision.
void box_mean(const cv::Mat& values, const cv::Mat& weights, int k, float min_weight, cv::Mat& out) {
  if (values.type() != CV_32F || weights.type() != CV_32F || values.size() != weights.size() || k < 1 ||
      k % 2 == 0 || !values.isContinuous() || !weights.isContinuous())
    throw std::invalid_argument("box_mean: two continuous CV_32F images of one size and an odd k");
  const int rows = values.rows, cols = values.cols, h = k / 2;
  out.create(rows, cols, CV_32F);
  const float* val = values.ptr<float>();
  const float* wgt = weights.ptr<float>();
  float* res = out.ptr<float>();
  const float nan = std::numeric_limits<float>::quiet_NaN();
#pragma omp parallel
  {
    std::vector<double> col_v(static_cast<std::size_t>(cols) + k, 0.0), col_w(col_v.size(), 0.0);
    // Column c's sums at index c + h, zeros on both sides for the window's overhang.
    double* cv_ = col_v.data() + h;
    double* cw = col_w.data() + h;
    const auto add_row = [&](int r, double sign) {
      if (r < 0 || r >= rows) return;
      const float* v = val + static_cast<std::ptrdiff_t>(r) * cols;
      const float* w = wgt + static_cast<std::ptrdiff_t>(r) * cols;
      for (int c = 0; c < cols; ++c) cv_[c] += sign * v[c], cw[c] += sign * w[c];
    };
    bool started = false;
#pragma omp for schedule(static)
    for (int r = 0; r < rows; ++r) {
      if (!started) {  // the first row of this thread's band: its window's rows
        for (int rr = r - h; rr <= r + h; ++rr) add_row(rr, 1.0);
        started = true;
      } else {
        add_row(r + h, 1.0);
        add_row(r - h - 1, -1.0);
      }
      double sv = 0.0, sw = 0.0;
      for (int c = -h; c < h; ++c) sv += cv_[c], sw += cw[c];
      float* o = res + static_cast<std::ptrdiff_t>(r) * cols;
      for (int c = 0; c < cols; ++c) {
        sv += cv_[c + h], sw += cw[c + h];
        o[c] = sw >= min_weight ? static_cast<float>(sv / std::max(sw, 1e-6)) : nan;
        sv -= cv_[c - h], sw -= cw[c - h];
      }
    }
  }
}

}  // namespace dentmark::detect
