#pragma once
// The median of a sample, as ingest measures spacings and image steps: the upper one for
// an even count, T{} for an empty sample. The sample is reordered.

#include <algorithm>
#include <cstddef>
#include <vector>

namespace dentmark::ingest {

template <typename T>
T median_in_place(std::vector<T>& v) {
  if (v.empty()) return T{};
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace dentmark::ingest
