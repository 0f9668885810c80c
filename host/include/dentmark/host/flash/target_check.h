#pragma once
// Whether a path may be overwritten with an image (dentmark flash). A target is either
// a regular file (new or existing; it is replaced whole) or a whole block device that
// nothing on this machine uses. Refused, each with a message naming the path and the
// reason:
//   - anything else (a folder, a character device, a pipe, a socket);
//   - a block device that is mounted, or one of whose partitions is mounted
//     (/proc/self/mountinfo), or that is active swap (/proc/swaps);
//   - a block device that holds the host's root or /boot filesystem, also through a
//     device-mapper or md layer (its holders in /sys/class/block/*/holders);
//   - a block device that another device is built on (LVM, dm-crypt, md: holders);
//   - a path that mountinfo names as the source of a mount (an image file mounted
//     through a loop device shows there by its path).
// The system's view (mountinfo and swaps text, the sysfs root) is passed in, so the
// rules can be tested with made-up tables.

#include <sys/types.h>

#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace dentmark::flash {

class FlashError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// One line of /proc/self/mountinfo (proc(5)); octal escapes (\040) decoded.
struct MountEntry {
  unsigned major = 0;
  unsigned minor = 0;
  std::string mount_point;
  std::string fs_type;
  std::string source;
};

// Parses mountinfo text; throws FlashError naming 'origin' and the line when a line
// does not have mountinfo's fields.
std::vector<MountEntry> parse_mountinfo(std::string_view text, const std::string& origin);

// The device paths of /proc/swaps text (its first column, header skipped).
std::vector<std::string> parse_swaps(std::string_view text);

struct SystemView {
  std::string mountinfo;                 // /proc/self/mountinfo
  std::string swaps;                     // /proc/swaps
  std::filesystem::path sysfs = "/sys";  // for partitions and holders
  static SystemView of_this_machine();   // reads the three above
};

enum class TargetKind { kNewFile, kRegularFile, kBlockDevice };

// The kind of 'target' when it may be written; throws FlashError naming it otherwise.
TargetKind check_target(const std::filesystem::path& target, const SystemView& system);

}  // namespace dentmark::flash
