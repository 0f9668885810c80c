#pragma once
// The OpenMP team the detector's parallel loops use (one thread without OpenMP).

#include <algorithm>

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

}  // namespace dentmark::detect::detail
