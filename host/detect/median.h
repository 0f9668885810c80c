#pragma once
// The median of a sample (the upper one for an even count); 0 for an empty sample.
#include <algorithm>
#include <cstddef>
#include <vector>

namespace dentmark::detect {

inline double median_of(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace dentmark::detect
