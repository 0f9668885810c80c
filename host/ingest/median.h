#pragma once
// The median of a sample, as ingest measures spacings and image steps: the upper one for
// an even count, T{} for an empty sample. The sample is reordered.

#include <vector>

#include "dentmark/common/nth_smallest.h"

namespace dentmark::ingest {

template <typename T>
T median_in_place(std::vector<T>& v) {
  return v.empty() ? T{} : nth_smallest(v, v.size() / 2);
}

}  // namespace dentmark::ingest
