#include "box_mean.h"

#include <omp.h>

#include <algorithm>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <vector>

#include "hot_loop.h"

namespace dentmark::detect {

// Both sums in one pass of running sums: column sums over the window's rows, moved down
// a row at a time, then row sums over the window's columns. Bands of rows go to the
// threads; sums are kept in double, so running them costs no precision. The row sums
// are a chain of dependent additions: two rows are run side by side, so that one row's
// additions fill the other's wait.
DENTMARK_HOT_LOOP void box_mean(const cv::Mat& values, const cv::Mat& weights, int k, float min_weight,
                                cv::Mat& out) {
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
    // Column sums of two consecutive rows, column c at index c + h, zeros on both sides
    // for the window's overhang.
    std::vector<double> buf(4 * (static_cast<std::size_t>(cols) + k), 0.0);
    const std::size_t stride = static_cast<std::size_t>(cols) + k;
    double* sv[2] = {buf.data() + h, buf.data() + stride + h};
    double* sw[2] = {buf.data() + 2 * stride + h, buf.data() + 3 * stride + h};
    const auto add_row = [&](double* cv_, double* cw, int r) {
      const float* v = val + static_cast<std::ptrdiff_t>(r) * cols;
      const float* w = wgt + static_cast<std::ptrdiff_t>(r) * cols;
      for (int c = 0; c < cols; ++c) cv_[c] += v[c], cw[c] += w[c];
    };
    // The next row's column sums from this row's, in one pass: row r + h in, row
    // r - h - 1 out (the same additions, in the same order, as moving one set down a
    // row). The overhangs stay zero.
    const auto next_row = [&](int from, int r) {
      const int to = 1 - from;
      const double *fv = sv[from], *fw = sw[from];
      double *tv = sv[to], *tw = sw[to];
      const bool enters = r + h < rows, leaves = r - h - 1 >= 0;
      const std::ptrdiff_t ri = static_cast<std::ptrdiff_t>(enters ? r + h : 0) * cols,
                           ro = static_cast<std::ptrdiff_t>(leaves ? r - h - 1 : 0) * cols;
      const float *vi = val + ri, *wi = wgt + ri, *vo = val + ro, *wo = wgt + ro;
      if (enters && leaves)
        for (int c = 0; c < cols; ++c) tv[c] = (fv[c] + vi[c]) - vo[c], tw[c] = (fw[c] + wi[c]) - wo[c];
      else if (enters)
        for (int c = 0; c < cols; ++c) tv[c] = fv[c] + vi[c], tw[c] = fw[c] + wi[c];
      else if (leaves)
        for (int c = 0; c < cols; ++c) tv[c] = fv[c] - vo[c], tw[c] = fw[c] - wo[c];
      else
        std::copy(fv, fv + cols, tv), std::copy(fw, fw + cols, tw);
    };
    const auto emit = [&](int n, int first, int r) {  // rows r .. r + n - 1 from sets first, 1 - first
      double a[2] = {0.0, 0.0}, b[2] = {0.0, 0.0};
      const double* cv0 = sv[first];
      const double* cw0 = sw[first];
      const double* cv1 = sv[1 - first];
      const double* cw1 = sw[1 - first];
      for (int c = -h; c < h; ++c) a[0] += cv0[c], b[0] += cw0[c];
      if (n == 2)
        for (int c = -h; c < h; ++c) a[1] += cv1[c], b[1] += cw1[c];
      float* o0 = res + static_cast<std::ptrdiff_t>(r) * cols;
      if (n == 1) {
        for (int c = 0; c < cols; ++c) {
          a[0] += cv0[c + h], b[0] += cw0[c + h];
          o0[c] = b[0] >= min_weight ? static_cast<float>(a[0] / std::max(b[0], 1e-6)) : nan;
          a[0] -= cv0[c - h], b[0] -= cw0[c - h];
        }
        return;
      }
      float* o1 = o0 + cols;
      for (int c = 0; c < cols; ++c) {
        a[0] += cv0[c + h], b[0] += cw0[c + h];
        a[1] += cv1[c + h], b[1] += cw1[c + h];
        o0[c] = b[0] >= min_weight ? static_cast<float>(a[0] / std::max(b[0], 1e-6)) : nan;
        o1[c] = b[1] >= min_weight ? static_cast<float>(a[1] / std::max(b[1], 1e-6)) : nan;
        a[0] -= cv0[c - h], b[0] -= cw0[c - h];
        a[1] -= cv1[c - h], b[1] -= cw1[c - h];
      }
    };
    // This thread's band, as schedule(static) would give it.
    const int threads = omp_get_num_threads(), t = omp_get_thread_num();
    const int q = rows / threads, extra = rows % threads;
    const int r0 = t * q + std::min(t, extra), r1 = r0 + q + (t < extra ? 1 : 0);
    if (r0 < r1) {
      for (int rr = std::max(r0 - h, 0); rr <= std::min(r0 + h, rows - 1); ++rr) add_row(sv[0], sw[0], rr);
      int cur = 0;
      for (int r = r0; r < r1; r += 2) {
        if (r + 1 < r1) {
          next_row(cur, r + 1);
          emit(2, cur, r);
          if (r + 2 < r1) next_row(1 - cur, r + 2);  // (into this row's set)
        } else {
          emit(1, cur, r);
        }
      }
    }
  }
}

}  // namespace dentmark::detect
