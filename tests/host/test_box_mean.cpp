// box_mean: the windowed weighted mean against a brute-force sum over each window, at
// the image borders, for windows larger than the image, and whatever the thread count.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <opencv2/core.hpp>
#include <random>

#include "../../host/detect/box_mean.h"

namespace dentmark::detect {
namespace {

void expect_matches_brute_force(int rows, int cols, int k, float min_weight, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> value(-1e-4f, 1e-4f), weight(0.2f, 1.5f), coin(0.0f, 1.0f);
  cv::Mat w(rows, cols, CV_32F), v(rows, cols, CV_32F);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const bool seen = coin(rng) > 0.3f;  // a third unseen: weight and value 0
      w.at<float>(r, c) = seen ? weight(rng) : 0.0f;
      v.at<float>(r, c) = seen ? w.at<float>(r, c) * value(rng) : 0.0f;
    }
  cv::Mat out;
  box_mean(v, w, k, min_weight, out);
  ASSERT_EQ(out.size(), v.size());
  const int h = k / 2;
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      double sv = 0, sw = 0;
      for (int rr = std::max(0, r - h); rr <= std::min(rows - 1, r + h); ++rr)
        for (int cc = std::max(0, c - h); cc <= std::min(cols - 1, c + h); ++cc)
          sv += v.at<float>(rr, cc), sw += w.at<float>(rr, cc);
      const float got = out.at<float>(r, c);
      if (sw < min_weight) {
        EXPECT_TRUE(std::isnan(got)) << r << "," << c;
      } else {
        EXPECT_NEAR(got, sv / sw, 1e-6 * std::abs(sv / sw) + 1e-12) << r << "," << c;
      }
    }
}

TEST(BoxMean, EqualsTheSumOverEachWindow) {
  for (int k : {1, 3, 7, 15}) {
    SCOPED_TRACE(k);
    expect_matches_brute_force(57, 83, k, 0.3f * static_cast<float>(k * k),
                               1u + static_cast<std::uint32_t>(k));
  }
}

TEST(BoxMean, WindowsLargerThanTheImage) {
  expect_matches_brute_force(1, 40, 7, 1.0f, 2);
  expect_matches_brute_force(40, 1, 7, 1.0f, 3);
  expect_matches_brute_force(3, 4, 21, 2.0f, 4);
}

TEST(BoxMean, TheSameWhateverTheThreadCount) {
  const int initial = omp_get_max_threads();
  for (int threads = 1; threads <= 4; ++threads) {
    SCOPED_TRACE(threads);
    omp_set_num_threads(threads);
    expect_matches_brute_force(31, 29, 5, 3.0f, 5);
  }
  omp_set_num_threads(initial);
}

TEST(BoxMean, RejectsWhatItCannotFilter) {
  cv::Mat a(4, 4, CV_32F, cv::Scalar(0)), b(4, 5, CV_32F, cv::Scalar(0)), d(4, 4, CV_64F), out;
  EXPECT_THROW(box_mean(a, b, 3, 1.0f, out), std::invalid_argument);
  EXPECT_THROW(box_mean(a, d, 3, 1.0f, out), std::invalid_argument);
  EXPECT_THROW(box_mean(a, a, 4, 1.0f, out), std::invalid_argument);
}

}  // namespace
}  // namespace dentmark::detect
