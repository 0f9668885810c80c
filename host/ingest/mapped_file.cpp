#include "mapped_file.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "dentmark/host/ingest/mesh.h"

namespace dentmark::ingest::detail {
namespace {
#ifdef MADV_POPULATE_READ
constexpr int kPopulateRead = MADV_POPULATE_READ;
#else
constexpr int kPopulateRead = 22;  // Linux 5.14; older glibc headers lack the name
#endif
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
    if (::madvise(p, size_, kPopulateRead) != 0 && errno != EINVAL) {
      const int err = errno;
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
  if (mapped_) ::munmap(const_cast<char*>(data_), size_);
}

}  // namespace dentmark::ingest::detail
