#pragma once
// Files that are either wholly there or not at all: every writer of a result, a job or
// a calibration goes through here. The bytes go to a temporary file in the same
// folder, are flushed to the disk (fsync), and the file is renamed over the target,
// then the folder is flushed too, so that a power cut leaves the old file or the new
// one, never half of one. A target that is a device, a pipe or a socket (/dev/null,
// /dev/stdout, a FIFO) is written in place: a rename would replace the device node.
// Append-only logs (journals) use AppendLog, which flushes every record before it
// returns.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>

namespace dentmark::files {

class FileError : public std::runtime_error {
 public:
  FileError(const std::filesystem::path& path, const std::string& problem);
};

// Replaces 'path' with 'bytes' atomically. Throws FileError naming the file and the
// system's reason; the target is untouched and no temporary file is left then.
void write_atomically(const std::filesystem::path& path, std::span<const std::uint8_t> bytes);
void write_atomically(const std::filesystem::path& path, std::string_view text);
// The same for writers that need a file name (image and YAML libraries, streamed
// writers): 'write' writes the whole file at the temporary path it is given (same
// folder, same extension, so a library that picks its format by extension still
// does), then it is flushed and renamed over 'path'. An exception from 'write'
// removes the temporary file and passes on unchanged.
void write_atomically_with(const std::filesystem::path& path,
                           const std::function<void(const std::filesystem::path& tmp)>& write);

// A whole folder written at once (a recorded sequence): 'fill' writes into a fresh
// sibling folder it is given, which is then renamed to 'dir'. 'dir' may exist only as
// an empty folder. Throws FileError naming the folder; an exception from 'fill' removes
// the sibling and passes on unchanged.
void write_directory_atomically(const std::filesystem::path& dir,
                                const std::function<void(const std::filesystem::path& tmp)>& fill);

// The whole file; throws FileError naming the file when it cannot be read.
std::string read_all(const std::filesystem::path& path);

// An append-only text log: each append() writes one line and fsyncs before returning,
// so a line that was appended survives a crash or power cut.
class AppendLog {
 public:
  explicit AppendLog(const std::filesystem::path& path);  // creates the file when missing
  ~AppendLog();
  AppendLog(const AppendLog&) = delete;
  AppendLog& operator=(const AppendLog&) = delete;
  void append(std::string_view line);  // without the newline
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
  int fd_ = -1;
};

}  // namespace dentmark::files
