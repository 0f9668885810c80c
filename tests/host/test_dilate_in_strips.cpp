// dilate_in_strips against cv::dilate on the whole image: random masks, the kernels the
// detector uses and others, images smaller than the kernel, in place, any thread count.
// And the side-by-side runner beneath it: every job runs, an exception comes back.
#include <gtest/gtest.h>
#include <omp.h>

#include <atomic>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <stdexcept>

#include "../../host/detect/dilate.h"
#include "../../host/detect/threads.h"

namespace dentmark::detect {
namespace {

cv::Mat random_mask(int rows, int cols, double density, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::bernoulli_distribution set(density);
  cv::Mat m(rows, cols, CV_8U);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) m.at<std::uint8_t>(r, c) = set(rng) ? 255 : 0;
  return m;
}

void expect_same_as_opencv(const cv::Mat& src, const cv::Mat& kernel) {
  cv::Mat expected, got;
  cv::dilate(src, expected, kernel);
  dilate_in_strips(src, got, kernel);
  ASSERT_EQ(got.size(), src.size());
  ASSERT_EQ(got.type(), src.type());
  EXPECT_EQ(cv::countNonZero(got != expected), 0)
      << src.rows << " x " << src.cols << ", kernel " << kernel.rows << " x " << kernel.cols;
}

class ThreadCount : public ::testing::TestWithParam<int> {
 protected:
  void SetUp() override {
    initial_ = omp_get_max_threads();
    omp_set_num_threads(GetParam());
  }
  void TearDown() override { omp_set_num_threads(initial_); }
  int initial_ = 1;
};

TEST_P(ThreadCount, SameAsWholeImageDilation) {
  std::uint32_t seed = 1;
  for (const cv::Size size : {cv::Size(240, 180), cv::Size(37, 301), cv::Size(64, 9), cv::Size(5, 1)})
    for (const double density : {0.002, 0.05, 0.5})
      for (const int shape : {cv::MORPH_ELLIPSE, cv::MORPH_RECT, cv::MORPH_CROSS})
        for (const int side : {1, 3, 5, 7, 17, 51})
          expect_same_as_opencv(random_mask(size.height, size.width, density, seed++),
                                cv::getStructuringElement(shape, {side, side}));
}

TEST_P(ThreadCount, SameInPlaceAndIntoAnOldBuffer) {
  const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_ELLIPSE, {9, 9});
  const cv::Mat src = random_mask(200, 150, 0.01, 7);
  cv::Mat expected;
  cv::dilate(src, expected, kernel);
  cv::Mat in_place = src.clone();
  dilate_in_strips(in_place, in_place, kernel);
  EXPECT_EQ(cv::countNonZero(in_place != expected), 0);
  cv::Mat old(200, 150, CV_8U, cv::Scalar(255));
  const std::uint8_t* buffer = old.data;
  dilate_in_strips(src, old, kernel);
  EXPECT_EQ(old.data, buffer);  // reused, as cv::dilate would
  EXPECT_EQ(cv::countNonZero(old != expected), 0);
  cv::Mat wrong_size(3, 4, CV_8U, cv::Scalar(255));
  dilate_in_strips(src, wrong_size, kernel);
  EXPECT_EQ(cv::countNonZero(wrong_size != expected), 0);
}

TEST_P(ThreadCount, SideBySideRunsEveryJobOnce) {
  std::atomic<int> runs[5] = {};
  detail::side_by_side([&] { ++runs[0]; }, [&] { ++runs[1]; }, [&] { ++runs[2]; }, [&] { ++runs[3]; },
                       [&] { ++runs[4]; });
  for (const auto& r : runs) EXPECT_EQ(r.load(), 1);
}

TEST_P(ThreadCount, SideBySideRethrowsTheFirstFailedJobsException) {
  std::atomic<int> finished{0};
  try {
    detail::side_by_side([&] { ++finished; }, [] { throw std::runtime_error("second"); },
                         [] { throw std::logic_error("third"); }, [&] { ++finished; });
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "second");
  }
  EXPECT_EQ(finished.load(), 2);  // the others still ran to the end
}

INSTANTIATE_TEST_SUITE_P(Threads, ThreadCount, ::testing::Values(1, 2, 3, 7));

}  // namespace
}  // namespace dentmark::detect
