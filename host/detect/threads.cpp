#include "threads.h"

#include <exception>
#include <vector>

namespace dentmark::detect::detail {

void for_each_part(std::size_t n, const std::function<void(std::size_t)>& job) {
  std::vector<std::exception_ptr> error(n);
#pragma omp parallel for schedule(dynamic, 1)
  for (std::size_t i = 0; i < n; ++i) {
    try {
      job(i);
    } catch (...) {
      error[i] = std::current_exception();
    }
  }
  for (const auto& e : error)
    if (e) std::rethrow_exception(e);
}

}  // namespace dentmark::detect::detail
