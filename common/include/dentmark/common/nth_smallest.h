#pragma once
// The k-th smallest element of a sample (the value std::nth_element puts at position k),
// and the median, exactly, in about one pass over a large sample. Two order statistics of
// a strided subsample bracket it; the selection then runs only on the elements between
// them.
// (Introselect reads a 60 k sample several times: the dozen robust sigmas of a detection
// spent 0.5 ms each in it.) Where the bracket misses (a sample in a pattern the stride
// falls in step with), the whole sample is selected in as before. The values must be
// numbers ordered by < (no NaN).

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <memory>
#include <type_traits>
#include <vector>

namespace dentmark {

// The k-th smallest (0-based) of v, k < v.size(). v may be reordered.
template <typename T>
T nth_smallest(std::vector<T>& v, std::size_t k) {
  static_assert(std::is_arithmetic_v<T>);
  const std::size_t n = v.size();
  // Below this introselect is as fast.
  constexpr std::size_t kMinBracketed = 8192;
  if (n >= kMinBracketed) {
    const std::size_t m = std::clamp<std::size_t>(n / 32, 256, 32768);
    std::vector<T> sample(m);
    for (std::size_t i = 0; i < m; ++i) sample[i] = v[i * n / m];
    // k's rank in the subsample spreads by at most sqrt(m) / 2: the bracket is six of
    // those either side.
    const auto at =
        static_cast<std::size_t>(static_cast<double>(k) * static_cast<double>(m) / static_cast<double>(n));
    const auto margin = static_cast<std::size_t>(3.0 * std::sqrt(static_cast<double>(m))) + 1;
    const std::size_t ilo = at > margin ? at - margin : 0, ihi = std::min(m - 1, at + margin);
    std::nth_element(sample.begin(), sample.begin() + static_cast<std::ptrdiff_t>(ilo), sample.end());
    const T lo = sample[ilo];
    std::nth_element(sample.begin() + static_cast<std::ptrdiff_t>(ilo),
                     sample.begin() + static_cast<std::ptrdiff_t>(ihi), sample.end());
    const T hi = sample[ihi];
    // In sorted order: `below` elements under lo, then those in [lo, hi], then the rest.
    // (Without branches: which side of lo an element lies is a coin toss. Each element
    // is written at the end of those kept so far, which moves on only if it is kept: of
    // the block for n only as much is touched as the bracket holds.)
    const std::unique_ptr<T[]> between(new T[n]);
    std::size_t below = 0, count = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const T x = v[i];
      const bool under = x < lo, over = hi < x;
      between[count] = x;
      count += static_cast<std::size_t>(!under & !over);
      below += static_cast<std::size_t>(under);
    }
    if (below <= k && k < below + count) {
      T* const first = between.get();
      std::nth_element(first, first + (k - below), first + count);
      return first[k - below];
    }
  }
  const auto it = v.begin() + static_cast<std::ptrdiff_t>(k);
  std::nth_element(v.begin(), it, v.end());
  return *it;
}

// The median of a sample: the upper one for an even count, T{} for an empty sample.
template <typename T>
T median_in_place(std::vector<T>& v) {  // v may be reordered
  return v.empty() ? T{} : nth_smallest(v, v.size() / 2);
}
template <typename T>
T median_of(std::vector<T> v) {  // v as it was
  return median_in_place(v);
}

// The median absolute deviation times this is the standard deviation of Gaussian
// noise (1 / Φ⁻¹(3/4)): the robust sigma used throughout.
inline constexpr double kMadToSigma = 1.4826;

// The robust sigma of values about zero (residuals, deviations): kMadToSigma × their
// median absolute value. 'abs_values' must already be absolute values.
inline double robust_sigma(std::vector<double> abs_values) {
  return kMadToSigma * median_of(std::move(abs_values));
}

}  // namespace dentmark
