#include "radix_sort.h"

#include <algorithm>
#include <array>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace dentmark::detect::detail {

void radix_sort(std::vector<std::uint64_t>& data, int lo, int bits) {
  constexpr int kDigit = 11;
  constexpr std::size_t kBuckets = 1u << kDigit;
  const std::size_t n = data.size();
  if (n < 2 || bits <= 0) return;
  std::vector<std::uint64_t> tmp(n);
  int threads = 1;
#ifdef _OPENMP
  threads = std::max(1, omp_get_max_threads());
#endif
  std::vector<std::array<std::size_t, kBuckets>> hist(static_cast<std::size_t>(threads));
  std::uint64_t* src = data.data();
  std::uint64_t* dst = tmp.data();
  for (int shift = lo; shift < lo + bits; shift += kDigit) {
    const int width = std::min(kDigit, lo + bits - shift);
    const std::uint64_t mask = (1ull << width) - 1;
#pragma omp parallel num_threads(threads)
    {
      int t = 0;
#ifdef _OPENMP
      t = omp_get_thread_num();
#endif
      const std::size_t b = n * static_cast<std::size_t>(t) / static_cast<std::size_t>(threads),
                        e = n * static_cast<std::size_t>(t + 1) / static_cast<std::size_t>(threads);
      auto& h = hist[static_cast<std::size_t>(t)];
      h.fill(0);
      for (std::size_t i = b; i < e; ++i) ++h[(src[i] >> shift) & mask];
#pragma omp barrier
#pragma omp single
      {
        std::size_t sum = 0;
        for (std::size_t d = 0; d < kBuckets; ++d)
          for (int k = 0; k < threads; ++k) {
            const std::size_t c = hist[static_cast<std::size_t>(k)][d];
            hist[static_cast<std::size_t>(k)][d] = sum;
            sum += c;
          }
      }
      for (std::size_t i = b; i < e; ++i) dst[h[(src[i] >> shift) & mask]++] = src[i];
    }
    std::swap(src, dst);
  }
  if (src != data.data()) data.swap(tmp);
}

}  // namespace dentmark::detect::detail
