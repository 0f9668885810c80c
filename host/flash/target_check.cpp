#include "dentmark/host/flash/target_check.h"

#include <sys/stat.h>
#include <sys/sysmacros.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <set>
#include <sstream>

namespace dentmark::flash {
namespace fs = std::filesystem;
namespace {

std::string read_text(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw FlashError(path.string() + ": cannot read: " + std::strerror(errno));
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// mountinfo writes space, tab, newline and backslash in paths as \ooo (octal).
std::string unescape(std::string_view field) {
  std::string out;
  for (std::size_t i = 0; i < field.size(); ++i) {
    if (field[i] == '\\' && i + 3 < field.size()) {
      const std::string_view oct = field.substr(i + 1, 3);
      if (oct.find_first_not_of("01234567") == std::string_view::npos) {
        out += static_cast<char>(std::stoi(std::string(oct), nullptr, 8));
        i += 3;
        continue;
      }
    }
    out += field[i];
  }
  return out;
}

std::vector<std::string> split_spaces(std::string_view line) {
  std::vector<std::string> fields;
  std::istringstream in{std::string(line)};
  for (std::string f; in >> f;) fields.push_back(f);
  return fields;
}

struct DevNumber {
  unsigned major = 0;
  unsigned minor = 0;
  auto operator<=>(const DevNumber&) const = default;
};

std::string dev_name(DevNumber d) {
  return std::to_string(d.major) + ":" + std::to_string(d.minor);
}

// The device's folder under /sys/devices (through /sys/dev/block/MAJ:MIN), or empty.
fs::path block_dir(const fs::path& sysfs, DevNumber d) {
  std::error_code ec;
  fs::path dir = fs::canonical(sysfs / "dev" / "block" / dev_name(d), ec);
  return ec ? fs::path{} : dir;
}

// The whole disks a device lives on: itself, or the disk of a partition, and through
// device-mapper or md the disks of its slaves, recursively.
void underlying_disks(const fs::path& dir, std::set<fs::path>& disks, int depth = 0) {
  if (dir.empty() || depth > 16) return;
  std::error_code ec;
  if (fs::exists(dir / "partition", ec)) {
    disks.insert(dir.parent_path());
    return;
  }
  disks.insert(dir);
  if (fs::is_directory(dir / "slaves", ec)) {
    for (const auto& s : fs::directory_iterator(dir / "slaves", ec))
      underlying_disks(fs::canonical(s.path(), ec), disks, depth + 1);
  }
}

// The device numbers a mount stands on: mountinfo's own, and its source's when that is
// a block device (btrfs reports an anonymous device number in mountinfo).
std::vector<DevNumber> mount_devices(const MountEntry& m) {
  std::vector<DevNumber> devs{{m.major, m.minor}};
  struct stat st {};
  if (!m.source.empty() && m.source[0] == '/' && ::stat(m.source.c_str(), &st) == 0 && S_ISBLK(st.st_mode))
    devs.push_back({::major(st.st_rdev), ::minor(st.st_rdev)});
  return devs;
}

bool is_host_system_mount(const std::string& mount_point) {
  return mount_point == "/" || mount_point == "/boot" || mount_point == "/boot/efi" || mount_point == "/usr";
}

std::string kind_of(mode_t mode) {
  if (S_ISDIR(mode)) return "a folder";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISFIFO(mode)) return "a pipe";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

void refuse_mount_source(const fs::path& target, const fs::path& canonical,
                         const std::vector<MountEntry>& mounts) {
  for (const auto& m : mounts)
    if (m.source == target.string() || m.source == canonical.string())
      throw FlashError(target.string() + ": refused: it is mounted at " + m.mount_point +
                       " (the source of that " + m.fs_type + " mount)");
}

// A regular file that a loop device reads (losetup) is in use as a disk.
void refuse_loop_backing(const fs::path& target, const fs::path& canonical, const fs::path& sysfs) {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(sysfs / "block", ec)) {
    const fs::path backing = e.path() / "loop" / "backing_file";
    if (!fs::exists(backing, ec)) continue;
    std::string b = read_text(backing);
    while (!b.empty() && (b.back() == '\n' || b.back() == ' ')) b.pop_back();
    if (b == canonical.string())
      throw FlashError(target.string() + ": refused: it is attached to /dev/" + e.path().filename().string() +
                       " (losetup)");
  }
}

void refuse_used_block_device(const fs::path& target, DevNumber dev, const SystemView& system,
                              const std::vector<MountEntry>& mounts) {
  const fs::path dir = block_dir(system.sysfs, dev);
  std::error_code ec;
  if (!dir.empty() && fs::exists(dir / "partition", ec))
    throw FlashError(target.string() + ": refused: it is partition " + dir.filename().string() + " of /dev/" +
                     dir.parent_path().filename().string() + "; an image goes onto the whole device");

  // Mounts on the device or on one of its partitions, the host's own first.
  const MountEntry* hit = nullptr;
  for (const auto& m : mounts) {
    for (DevNumber d : mount_devices(m)) {
      std::set<fs::path> disks;
      underlying_disks(block_dir(system.sysfs, d), disks);
      const bool same = d == dev || (!dir.empty() && disks.count(dir));
      if (!same) continue;
      if (!hit || (is_host_system_mount(m.mount_point) && !is_host_system_mount(hit->mount_point))) hit = &m;
    }
  }
  if (hit && is_host_system_mount(hit->mount_point))
    throw FlashError(target.string() + ": refused: it holds this machine's " +
                     (hit->mount_point == "/" ? std::string("root") : hit->mount_point) + " filesystem (" +
                     hit->source + " mounted at " + hit->mount_point + ")");
  if (hit)
    throw FlashError(target.string() + ": refused: " + hit->source + " on it is mounted at " +
                     hit->mount_point + "; unmount it first");

  for (const auto& swap : parse_swaps(system.swaps)) {
    struct stat st {};
    if (::stat(swap.c_str(), &st) != 0 || !S_ISBLK(st.st_mode)) continue;
    const DevNumber d{::major(st.st_rdev), ::minor(st.st_rdev)};
    std::set<fs::path> disks;
    underlying_disks(block_dir(system.sysfs, d), disks);
    if (d == dev || (!dir.empty() && disks.count(dir)))
      throw FlashError(target.string() + ": refused: " + swap + " on it is active swap");
  }

  // A device something else is built on (LVM, dm-crypt, md), directly or through a partition.
  if (!dir.empty()) {
    std::vector<fs::path> dirs{dir};
    for (const auto& e : fs::directory_iterator(dir, ec))
      if (fs::exists(e.path() / "partition", ec)) dirs.push_back(e.path());
    for (const auto& d : dirs)
      for (const auto& h : fs::directory_iterator(d / "holders", ec))
        throw FlashError(target.string() + ": refused: " + d.filename().string() + " is in use by " +
                         h.path().filename().string() + " (device-mapper, LVM or md)");
  }
}

}  // namespace

std::vector<MountEntry> parse_mountinfo(std::string_view text, const std::string& origin) {
  std::vector<MountEntry> mounts;
  std::size_t line_no = 0;
  std::istringstream in{std::string(text)};
  for (std::string line; std::getline(in, line);) {
    ++line_no;
    if (line.empty()) continue;
    const auto f = split_spaces(line);
    // id parent major:minor root mount_point options [optional...] - fstype source super
    std::size_t dash = 6;
    while (dash < f.size() && f[dash] != "-") ++dash;
    unsigned maj = 0, min = 0;
    char colon = 0;
    std::istringstream dev(f.size() > 2 ? f[2] : "");
    const bool dev_ok = static_cast<bool>(dev >> maj >> colon >> min) && colon == ':';
    if (f.size() < 7 || dash + 2 >= f.size() || !dev_ok)
      throw FlashError(origin + ": line " + std::to_string(line_no) +
                       ": not a mountinfo line (id parent major:minor root mount-point options "
                       "... - type source options)");
    MountEntry m;
    m.major = maj;
    m.minor = min;
    m.mount_point = unescape(f[4]);
    m.fs_type = f[dash + 1];
    m.source = unescape(f[dash + 2]);
    mounts.push_back(std::move(m));
  }
  return mounts;
}

std::vector<std::string> parse_swaps(std::string_view text) {
  std::vector<std::string> devices;
  std::istringstream in{std::string(text)};
  std::string line;
  std::getline(in, line);  // Filename Type Size Used Priority
  while (std::getline(in, line)) {
    const auto f = split_spaces(line);
    if (!f.empty()) devices.push_back(unescape(f[0]));
  }
  return devices;
}

SystemView SystemView::of_this_machine() {
  SystemView v;
  v.mountinfo = read_text("/proc/self/mountinfo");
  std::error_code ec;
  if (fs::exists("/proc/swaps", ec)) v.swaps = read_text("/proc/swaps");
  return v;
}

TargetKind check_target(const fs::path& target, const SystemView& system) {
  const auto mounts = parse_mountinfo(system.mountinfo, "/proc/self/mountinfo");
  struct stat st {};
  if (::stat(target.c_str(), &st) != 0) {
    if (errno != ENOENT) throw FlashError(target.string() + ": cannot examine: " + std::strerror(errno));
    const fs::path parent = target.parent_path().empty() ? "." : target.parent_path();
    std::error_code ec;
    if (!fs::is_directory(parent, ec))
      throw FlashError(target.string() + ": refused: its folder " + parent.string() + " does not exist");
    return TargetKind::kNewFile;
  }
  std::error_code ec;
  const fs::path canonical = fs::canonical(target, ec);
  if (S_ISREG(st.st_mode)) {
    refuse_mount_source(target, ec ? target : canonical, mounts);
    refuse_loop_backing(target, ec ? target : canonical, system.sysfs);
    return TargetKind::kRegularFile;
  }
  if (!S_ISBLK(st.st_mode))
    throw FlashError(target.string() + ": refused: " + kind_of(st.st_mode) +
                     ", neither a block device nor a regular file");
  refuse_used_block_device(target, {::major(st.st_rdev), ::minor(st.st_rdev)}, system, mounts);
  return TargetKind::kBlockDevice;
}

}  // namespace dentmark::flash
