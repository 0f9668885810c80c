#include "dentmark/common/huge_pages.h"

#include <malloc.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace dentmark {
namespace {

constexpr const char* kTunable = "glibc.malloc.hugetlb=1";

}  // namespace

void keep_freed_memory_for_reuse() {
  mallopt(M_ARENA_MAX, 1);
  mallopt(M_MMAP_MAX, 0);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
}

bool huge_pages_requested() {
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  return tunables && std::strstr(tunables, kTunable);
}

void reexec_with_huge_pages() {
  const char* off = std::getenv("DENTMARK_HUGEPAGES");
  if (off && std::strcmp(off, "0") == 0) return;
  const char* current = std::getenv("GLIBC_TUNABLES");
  if (current && std::strstr(current, "glibc.malloc.hugetlb")) return;  // set (by us or the user)
  // The arguments as the kernel holds them (works before main has its argv, too).
  std::ifstream in("/proc/self/cmdline", std::ios::binary);
  const std::string cmdline((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (cmdline.empty()) return;
  std::vector<char*> argv;
  for (std::size_t at = 0; at < cmdline.size(); at = cmdline.find('\0', at) + 1)
    argv.push_back(const_cast<char*>(cmdline.c_str() + at));
  argv.push_back(nullptr);
  const std::string previous = current ? current : "";
  const std::string tunables = previous.empty() ? kTunable : previous + ":" + kTunable;
  if (::setenv("GLIBC_TUNABLES", tunables.c_str(), 1) != 0) return;
  ::execv("/proc/self/exe", argv.data());
  // Exec failed: carry on as we are.
  if (current)
    ::setenv("GLIBC_TUNABLES", previous.c_str(), 1);
  else
    ::unsetenv("GLIBC_TUNABLES");
}

}  // namespace dentmark
