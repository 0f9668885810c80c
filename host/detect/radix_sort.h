#pragma once
// LSD radix sort of 64-bit words on bits [lo, lo + bits), 11 bits per pass, each pass
// split over the OpenMP threads (per-thread histograms, stable scatter).

#include <cstdint>
#include <vector>

namespace dentmark::detect::detail {

void radix_sort(std::vector<std::uint64_t>& data, int lo, int bits);

}  // namespace dentmark::detect::detail
