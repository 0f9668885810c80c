#include "dentmark/common/huge_pages.h"

#include <malloc.h>
#include <sys/mman.h>

#include <climits>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>

namespace dentmark {
namespace {

constexpr std::size_t kReserve = std::size_t{1} << 30;
constexpr std::uintptr_t kHugePage = std::uintptr_t{2} << 20;
bool requested = false;

bool sanitized() {
#if defined(__SANITIZE_ADDRESS__)
  return true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
  return true;
#else
  return false;
#endif
#else
  return false;
#endif
}

}  // namespace

bool prepare_heap_for_big_jobs() {
  if (sanitized()) return false;
  mallopt(M_ARENA_MAX, 1);
  mallopt(M_MMAP_MAX, 0);
  mallopt(M_TRIM_THRESHOLD, INT_MAX);
  const char* on = std::getenv("DENTMARK_HUGEPAGES");
  if (!on || std::strcmp(on, "1") != 0) return false;
  // Grow the heap by kReserve of untouched address space and give it back to the
  // allocator: it stays the heap's top (no trimming), and every later block is cut
  // from it, inside the range marked for huge pages.
  void* block = std::malloc(kReserve);
  if (!block) return false;
  const auto begin = (reinterpret_cast<std::uintptr_t>(block) + kHugePage - 1) & ~(kHugePage - 1);
  const auto end = (reinterpret_cast<std::uintptr_t>(block) + kReserve) & ~(kHugePage - 1);
  requested = end > begin && ::madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE) == 0;
  std::free(block);
  return requested;
}

bool huge_pages_requested() {
  return requested;
}

std::size_t huge_page_bytes_in_use() {
  std::ifstream in("/proc/self/smaps_rollup");
  std::string key;
  std::size_t kb = 0;
  while (in >> key) {
    if (key == "AnonHugePages:") {
      in >> kb;
      return kb * 1024;
    }
    in.ignore(SIZE_MAX, '\n');
  }
  return 0;
}

}  // namespace dentmark
