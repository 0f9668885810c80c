#include "dentmark/common/ingest/detail/mapped_file.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstring>

#include "dentmark/common/ingest/mesh.h"

#ifdef _OPENMP
#include <omp.h>
#else
inline int omp_get_max_threads() {
  return 1;
}
#endif

namespace dentmark::ingest::detail {
namespace {
#ifdef MADV_POPULATE_READ
constexpr int kPopulateRead = MADV_POPULATE_READ;
#else
constexpr int kPopulateRead = 22;  // Linux 5.14; older glibc headers lack the name
#endif
// The mapping in 2 MB-aligned pieces, one per thread: piece i of n starts at the first
// 2 MB boundary (in the address space) from i / n of it.
std::size_t piece_start(const char* p, std::size_t size, std::size_t n, std::size_t i) {
  if (i == 0) return 0;
  if (i == n) return size;
  constexpr std::uintptr_t kAlign = std::uintptr_t{2} << 20;
  const std::uintptr_t a = reinterpret_cast<std::uintptr_t>(p) + size / n * i;
  return std::min(size, static_cast<std::size_t>(((a + kAlign - 1) & ~(kAlign - 1)) -
                                                 reinterpret_cast<std::uintptr_t>(p)));
}

// madvise(advice) over the pieces side by side. Returns 0 or the errno of a failure other
// than `harmless`.
int advise_in_pieces(char* p, std::size_t size, int advice, int harmless) {
  const auto pieces = static_cast<std::size_t>(std::max(1, omp_get_max_threads()));
  int err = 0;
#pragma omp parallel for schedule(static, 1) reduction(max : err)
  for (std::size_t i = 0; i < pieces; ++i) {
    const std::size_t b = piece_start(p, size, pieces, i), e = piece_start(p, size, pieces, i + 1);
    if (b < e && ::madvise(p + b, e - b, advice) != 0 && errno != harmless) err = std::max(err, errno);
  }
  return err;
}

// Populates the mapping side by side: mapping a cached 170 MB scan is ~10 ms of
// page-table work for one thread. Returns 0 or the errno of a failure (EINVAL, a kernel
// without MADV_POPULATE_READ, is no failure: pages then fault in).
int populate(char* p, std::size_t size) {
  return advise_in_pieces(p, size, kPopulateRead, EINVAL);
}

}  // namespace

MappedFile::MappedFile(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw IngestError(path + ": cannot open: " + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    throw IngestError(path + ": not a regular file");
  }
  size_ = static_cast<std::size_t>(st.st_size);
  if (size_ > 0) {
    void* p = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd, 0);
    if (p == MAP_FAILED) {
      ::close(fd);
      throw IngestError(path + ": cannot map: " + std::strerror(errno));
    }
    data_ = static_cast<const char*>(p);
    mapped_ = true;
    // Asked for huge pages before it is populated: what is not cached yet is read into
    // 2 MB folios, which map with one entry per 2 MB (a scan written in large blocks is
    // cached that way already). Then populated up front: a scan used in place is read at
    // random (vertex gathers), so no sequential-access advice either. Both are advice:
    // an older kernel without them faults the pages in as they are read.
    ::madvise(p, size_, MADV_HUGEPAGE);
    if (const int err = populate(static_cast<char*>(p), size_); err != 0) {
      ::munmap(p, size_);
      ::close(fd);
      throw IngestError(path + ": cannot read: " + std::strerror(err));
    }
  } else {
    data_ = "";
  }
  ::close(fd);
}

MappedFile::~MappedFile() {
  if (!mapped_) return;
  // Unmapping a populated 170 MB scan is 3.5 ms of page-table work for one thread, under
  // the address space's write lock. Dropping its pages first takes the read lock, so the
  // pieces go side by side and what is left to unmap is empty (2 ms in all).
  advise_in_pieces(const_cast<char*>(data_), size_, MADV_DONTNEED, 0);
  ::munmap(const_cast<char*>(data_), size_);
}

}  // namespace dentmark::ingest::detail
