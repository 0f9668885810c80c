#include "dentmark/common/protocol/dml_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "dentmark/common/atomic_file.h"

namespace dentmark::protocol {

DmlFileError::DmlFileError(const std::string& path, const std::string& problem)
    : std::runtime_error(path + ": " + problem) {}
DmlFileError::DmlFileError(const std::string& path, const DecodeError& error)
    : std::runtime_error(path + ": " + error.message()), decode_error_(error) {}

void write_frame_file(const std::string& path, std::span<const std::uint8_t> frame) {
  try {
    files::write_atomically(path, frame);
  } catch (const files::FileError& e) {
    throw DmlFileError(path, std::string(e.what()).substr(path.size() + 2));
  }
}

void write_dml(const std::string& path, const DefectList& list, const EncodeOptions& options) {
  const auto frame = encode(list, options);
  write_frame_file(path, frame);
}

std::vector<std::uint8_t> read_frame_file(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw DmlFileError(path, std::string("cannot open: ") + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    throw DmlFileError(path, "not a regular file");
  }
  if (static_cast<std::uint64_t>(st.st_size) > wire::kMaxFrameSize) {
    ::close(fd);
    DecodeError e{DecodeErrorKind::kOverLimit, wire::kMaxFrameSize,
                  "file of " + std::to_string(st.st_size) + " bytes > frame limit " +
                      std::to_string(wire::kMaxFrameSize)};
    throw DmlFileError(path, e);
  }
  // One byte more than the limit detects a file that grew after fstat.
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(st.st_size) + 1);
  std::size_t got = 0;
  while (got < bytes.size()) {
    const ssize_t n = ::read(fd, bytes.data() + got, bytes.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const std::string why = std::strerror(errno);
      ::close(fd);
      throw DmlFileError(path, "read failed: " + why);
    }
    if (n == 0) break;
    got += static_cast<std::size_t>(n);
  }
  ::close(fd);
  if (got > static_cast<std::size_t>(st.st_size)) throw DmlFileError(path, "file changed while being read");
  bytes.resize(got);
  return bytes;
}

Decoded read_protocol_file(const std::string& path, const DecodeOptions& options) {
  const auto bytes = read_frame_file(path);
  auto r = decode(bytes, options);
  if (!r) throw DmlFileError(path, r.error());
  return std::move(r.value());
}

DefectList read_dml(const std::string& path, const DecodeOptions& options) {
  Decoded d = read_protocol_file(path, options);
  if (auto* list = std::get_if<DefectList>(&d.message)) return std::move(*list);
  throw DmlFileError(path, std::string("holds a ") + to_string(d.header.type) + ", not a DefectList");
}

}  // namespace dentmark::protocol
