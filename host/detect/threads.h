#pragma once
// The OpenMP team the detector's parallel loops use (one thread without OpenMP).

#include <algorithm>
#include <array>
#include <cstddef>
#include <functional>
#include <utility>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace dentmark::detect::detail {

inline int thread_count() {
#ifdef _OPENMP
  return std::max(1, omp_get_max_threads());
#else
  return 1;
#endif
}

inline int thread_index() {
#ifdef _OPENMP
  return omp_get_thread_num();
#else
  return 0;
#endif
}

// job(0), ..., job(n - 1) side by side, each thread taking the next one left. A job's
// exception is rethrown once all have finished (the first job's that threw).
void for_each_part(std::size_t n, const std::function<void(std::size_t)>& job);

// Independent jobs run side by side: serial work that would leave the other cores idle,
// above all filling fresh arrays (a page fault per 4 KB page).
template <class... Jobs>
void side_by_side(Jobs&&... jobs) {
  const std::array<std::function<void()>, sizeof...(Jobs)> list{std::forward<Jobs>(jobs)...};
  for_each_part(list.size(), [&](std::size_t i) { list[i](); });
}

}  // namespace dentmark::detect::detail
