#pragma once
// The median of a sample (the upper one for an even count); 0 for an empty sample.
#include <vector>

#include "dentmark/common/nth_smallest.h"

namespace dentmark::detect {

inline double median_of(std::vector<double> v) {
  return v.empty() ? 0.0 : nth_smallest(v, v.size() / 2);
}

}  // namespace dentmark::detect
