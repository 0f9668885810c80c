// label_components: areas and border contact against a flood fill done the slow way, for
// 4- and 8-connectivity, one-pixel images and whatever the thread count.
#include <gtest/gtest.h>
#include <omp.h>

#include <map>
#include <opencv2/core.hpp>
#include <random>
#include <utility>
#include <vector>

#include "../../host/detect/components.h"

namespace dentmark::detect {
namespace {

struct Truth {
  std::int32_t area = 0;
  bool touches_border = false;
};

// Each component's area and border contact by flood fill, keyed by its first pixel in
// row-major order (label numbers may differ; the partition may not).
std::map<int, Truth> flood_fill(const cv::Mat& mask, int connectivity) {
  const int rows = mask.rows, cols = mask.cols;
  std::vector<char> seen(static_cast<std::size_t>(rows * cols), 0);
  std::map<int, Truth> out;
  for (int start = 0; start < rows * cols; ++start) {
    if (!mask.data[start] || seen[static_cast<std::size_t>(start)]) continue;
    Truth& t = out[start];
    std::vector<int> stack{start};
    seen[static_cast<std::size_t>(start)] = 1;
    while (!stack.empty()) {
      const int k = stack.back();
      stack.pop_back();
      const int r = k / cols, c = k % cols;
      ++t.area;
      t.touches_border = t.touches_border || r == 0 || c == 0 || r == rows - 1 || c == cols - 1;
      for (int dr = -1; dr <= 1; ++dr)
        for (int dc = -1; dc <= 1; ++dc) {
          if ((dr == 0 && dc == 0) || (connectivity == 4 && dr != 0 && dc != 0)) continue;
          const int rr = r + dr, cc = c + dc, q = rr * cols + cc;
          if (rr < 0 || cc < 0 || rr >= rows || cc >= cols || !mask.data[q] ||
              seen[static_cast<std::size_t>(q)])
            continue;
          seen[static_cast<std::size_t>(q)] = 1;
          stack.push_back(q);
        }
    }
  }
  return out;
}

void expect_matches_flood_fill(const cv::Mat& mask, int connectivity) {
  const Components c = label_components(mask, connectivity);
  const std::map<int, Truth> truth = flood_fill(mask, connectivity);
  ASSERT_EQ(c.count, static_cast<int>(truth.size()) + 1);
  ASSERT_EQ(c.area.size(), truth.size() + 1);
  std::vector<char> used(static_cast<std::size_t>(c.count), 0);
  for (const auto& [first, t] : truth) {
    const int label = c.labels.at<int>(first / mask.cols, first % mask.cols);
    ASSERT_GT(label, 0);
    EXPECT_FALSE(used[static_cast<std::size_t>(label)]) << "two components share label " << label;
    used[static_cast<std::size_t>(label)] = 1;
    EXPECT_EQ(c.area[static_cast<std::size_t>(label)], t.area) << "component at pixel " << first;
    EXPECT_EQ(c.touches_border[static_cast<std::size_t>(label)] != 0, t.touches_border)
        << "component at pixel " << first;
  }
}

cv::Mat random_mask(int rows, int cols, double fill, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::bernoulli_distribution on(fill);
  cv::Mat m(rows, cols, CV_8U);
  for (int k = 0; k < rows * cols; ++k) m.data[k] = on(rng) ? 255 : 0;
  return m;
}

TEST(Components, AreasAndBorderContactMatchAFloodFill) {
  for (const int connectivity : {4, 8})
    for (const double fill : {0.1, 0.45, 0.6, 0.9}) {
      SCOPED_TRACE(::testing::Message() << connectivity << "-connected, fill " << fill);
      expect_matches_flood_fill(random_mask(97, 131, fill, 5), connectivity);
    }
}

TEST(Components, SmallAndEmptyImages) {
  for (const int connectivity : {4, 8}) {
    expect_matches_flood_fill(cv::Mat(1, 1, CV_8U, cv::Scalar(255)), connectivity);
    expect_matches_flood_fill(cv::Mat(1, 1, CV_8U, cv::Scalar(0)), connectivity);
    expect_matches_flood_fill(random_mask(1, 50, 0.5, 2), connectivity);
    expect_matches_flood_fill(random_mask(50, 1, 0.5, 3), connectivity);
    expect_matches_flood_fill(cv::Mat(40, 30, CV_8U, cv::Scalar(0)), connectivity);
  }
  // An enclosed blob does not touch the border; its ring does.
  cv::Mat ring(9, 9, CV_8U, cv::Scalar(255));
  ring(cv::Rect(1, 1, 7, 7)).setTo(0);
  ring(cv::Rect(3, 3, 3, 3)).setTo(255);
  const Components c = label_components(ring, 4);
  ASSERT_EQ(c.count, 3);
  const int outer = c.labels.at<int>(0, 0), inner = c.labels.at<int>(4, 4);
  EXPECT_EQ(c.area[static_cast<std::size_t>(outer)], 32);
  EXPECT_EQ(c.area[static_cast<std::size_t>(inner)], 9);
  EXPECT_TRUE(c.touches_border[static_cast<std::size_t>(outer)]);
  EXPECT_FALSE(c.touches_border[static_cast<std::size_t>(inner)]);
}

TEST(Components, SameWhateverTheThreadCount) {
  const int initial = omp_get_max_threads();
  for (int threads = 1; threads <= 4; ++threads) {
    SCOPED_TRACE(threads);
    omp_set_num_threads(threads);
    expect_matches_flood_fill(random_mask(203, 157, 0.55, 9), 8);
  }
  omp_set_num_threads(initial);
}

}  // namespace
}  // namespace dentmark::detect
