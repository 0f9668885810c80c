#include "dentmark/common/atomic_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>

namespace dentmark::files {
namespace {

std::string system_reason() {
  return std::strerror(errno);
}

bool write_whole(int fd, const std::uint8_t* data, std::size_t size) {
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(fd, data + done, size - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    done += static_cast<std::size_t>(n);
  }
  return true;
}

// The rename is only durable once the folder's entry is on the disk.
void sync_folder(const std::filesystem::path& path) {
  const std::filesystem::path folder = path.has_parent_path() ? path.parent_path() : ".";
  const int dfd = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd < 0) return;  // not fatal: the data itself is synced
  ::fsync(dfd);
  ::close(dfd);
}

// A temporary name beside 'path' (so that rename() stays on one file system), with
// its extension.
std::filesystem::path temporary_beside(const std::filesystem::path& path) {
  std::random_device rd;
  std::filesystem::path tmp = path;
  tmp.replace_extension();
  tmp += ".tmp." + std::to_string(::getpid()) + "." + std::to_string(rd());
  tmp += path.extension();
  return tmp;
}

void fsync_file(const std::filesystem::path& path, const std::filesystem::path& target) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0 || ::fsync(fd) != 0) {
    const std::string why = system_reason();
    if (fd >= 0) ::close(fd);
    throw FileError(target, "flush failed: " + why);
  }
  ::close(fd);
}

void rename_into_place(const std::filesystem::path& tmp, const std::filesystem::path& path) {
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string why = system_reason();
    ::unlink(tmp.c_str());
    throw FileError(path, "rename failed: " + why);
  }
  sync_folder(path);
}

// A device, a pipe or a socket (or a link to one: /dev/stdout): written in place, since a
// rename would put a plain file where it was (as root, /dev/null), and a temporary
// beside it cannot be made in /dev by anyone else.
bool is_special_file(const std::filesystem::path& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode);
}

void write_in_place(const std::filesystem::path& path, std::span<const std::uint8_t> bytes) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
  if (fd < 0) throw FileError(path, "cannot open: " + system_reason());
  if (!write_whole(fd, bytes.data(), bytes.size())) {
    const std::string why = system_reason();
    ::close(fd);
    throw FileError(path, "write failed: " + why);
  }
  ::close(fd);
}

}  // namespace

FileError::FileError(const std::filesystem::path& path, const std::string& problem)
    : std::runtime_error(path.string() + ": " + problem) {}

void write_directory_atomically(const std::filesystem::path& dir,
                                const std::function<void(const std::filesystem::path& tmp)>& fill) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::exists(dir, ec)) {
    if (!fs::is_directory(dir, ec) || !fs::is_empty(dir, ec))
      throw FileError(dir, "exists and is not an empty directory");
    fs::remove(dir, ec);
  }
  const fs::path parent = dir.has_parent_path() ? dir.parent_path() : fs::path(".");
  if (!fs::is_directory(parent, ec)) throw FileError(parent, "no such directory");
  const fs::path tmp = parent / (dir.filename().string() + ".partial-" + std::to_string(::getpid()));
  fs::remove_all(tmp, ec);
  try {
    fs::create_directories(tmp);
    fill(tmp);
    fs::rename(tmp, dir);
  } catch (const fs::filesystem_error& e) {
    fs::remove_all(tmp, ec);
    throw FileError(dir, e.code().message());
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
}

void write_atomically(const std::filesystem::path& path, std::span<const std::uint8_t> bytes) {
  if (is_special_file(path)) return write_in_place(path, bytes);
  const std::filesystem::path tmp = temporary_beside(path);
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) throw FileError(path, "cannot create a temporary file: " + system_reason());
  if (!write_whole(fd, bytes.data(), bytes.size()) || ::fsync(fd) != 0) {
    const std::string why = system_reason();
    ::close(fd);
    ::unlink(tmp.c_str());
    throw FileError(path, "write failed: " + why);
  }
  if (::close(fd) != 0) {
    const std::string why = system_reason();
    ::unlink(tmp.c_str());
    throw FileError(path, "write failed: " + why);
  }
  rename_into_place(tmp, path);
}

void write_atomically_with(const std::filesystem::path& path,
                           const std::function<void(const std::filesystem::path& tmp)>& write) {
  if (is_special_file(path)) return write(path);
  const std::filesystem::path tmp = temporary_beside(path);
  try {
    write(tmp);
    fsync_file(tmp, path);
  } catch (...) {
    ::unlink(tmp.c_str());
    throw;
  }
  rename_into_place(tmp, path);
}

void write_atomically(const std::filesystem::path& path, std::string_view text) {
  write_atomically(path, std::span(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
}

std::string read_all(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FileError(path, "cannot open: " + system_reason());
  std::ostringstream s;
  s << in.rdbuf();
  if (in.bad()) throw FileError(path, "read failed");
  return s.str();
}

AppendLog::AppendLog(const std::filesystem::path& path) : path_(path) {
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd_ < 0) throw FileError(path, "cannot open for appending: " + system_reason());
  sync_folder(path);
}

AppendLog::~AppendLog() {
  if (fd_ >= 0) ::close(fd_);
}

void AppendLog::append(std::string_view line) {
  std::string record(line);
  record += '\n';
  if (!write_whole(fd_, reinterpret_cast<const std::uint8_t*>(record.data()), record.size()) ||
      ::fdatasync(fd_) != 0)
    throw FileError(path_, "append failed: " + system_reason());
}

}  // namespace dentmark::files
