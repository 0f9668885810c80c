// nth_smallest: the value std::nth_element puts at k, on samples large enough to be
// bracketed, in orders a strided subsample can be fooled by.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

#include "dentmark/common/nth_smallest.h"

namespace {

using dentmark::nth_smallest;

template <typename T>
T reference(std::vector<T> v, std::size_t k) {
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

template <typename T>
void expect_every_rank_checked(const std::vector<T>& v, const char* what) {
  const auto n = static_cast<std::int64_t>(v.size());
  for (const std::int64_t rank :
       {std::int64_t{0}, n / 100, n / 4, n / 2 - 1, n / 2, n / 2 + 1, 3 * n / 4, n - 1}) {
    if (rank < 0 || rank >= n) continue;  // (a sample of one or two)
    const auto k = static_cast<std::size_t>(rank);
    std::vector<T> copy = v;
    EXPECT_EQ(nth_smallest(copy, k), reference(v, k)) << what << ", n " << n << ", k " << k;
  }
}

TEST(NthSmallest, EqualsNthElementOnRandomSamples) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 2e-5);
  for (const std::size_t n : {1u, 2u, 100u, 8191u, 8192u, 60000u, 1000003u}) {
    std::vector<double> v(n);
    for (auto& x : v) x = noise(rng);
    expect_every_rank_checked(v, "normal");
  }
}

TEST(NthSmallest, EqualsNthElementOnSortedAndReversedSamples) {
  std::vector<float> up(100000);
  for (std::size_t i = 0; i < up.size(); ++i) up[i] = static_cast<float>(i) * 0.5f;
  expect_every_rank_checked(up, "sorted");
  std::vector<float> down(up.rbegin(), up.rend());
  expect_every_rank_checked(down, "reversed");
}

TEST(NthSmallest, EqualsNthElementWhereTheStrideFallsInStepWithAPattern) {
  // Every element the subsample takes (i * n / m) is the smallest value, the rest large:
  // the bracket misses and the whole sample is selected in.
  const std::size_t n = 64000, m = n / 32;
  std::vector<double> v(n, 0.0);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> large(1.0, 2.0);
  for (auto& x : v) x = large(rng);
  for (std::size_t i = 0; i < m; ++i) v[i * n / m] = -1.0;
  expect_every_rank_checked(v, "patterned");
}

TEST(NthSmallest, EqualsNthElementWithManyTies) {
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> few(0, 4);
  std::vector<std::int32_t> v(50000);
  for (auto& x : v) x = few(rng);
  expect_every_rank_checked(v, "ties");
  std::vector<double> same(20000, 1.25);
  expect_every_rank_checked(same, "all equal");
}

}  // namespace
