// dentmark flash: the target checks (mounted, the host's own disk, not a disk at all),
// block maps, and writing a sparse image with bmaptool and verifying it read back.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "../support/temp_dir.h"
#include "dentmark/host/flash/bmap.h"
#include "dentmark/host/flash/flash.h"
#include "dentmark/host/flash/target_check.h"

namespace fs = std::filesystem;
using dentmark::flash::FlashError;
using dentmark::flash::SystemView;
using dentmark::flash::TargetKind;

namespace {

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const FlashError& e) {
    return e.what();
  }
  return "(no error)";
}

std::string read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_at(const fs::path& p, std::uint64_t offset, const std::string& bytes) {
  const int fd = ::open(p.c_str(), O_WRONLY);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::pwrite(fd, bytes.data(), bytes.size(), static_cast<off_t>(offset)),
            static_cast<ssize_t>(bytes.size()));
  ::close(fd);
}

std::string random_bytes(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::string s(n, '\0');
  for (auto& c : s) c = static_cast<char>(rng() & 0xff);
  return s;
}

// A sparse image of 'size' bytes with random data in a few places (one range ends in
// the middle of a block, and one is the image's last, partial block).
struct SparseImage {
  fs::path path;
  std::uint64_t size = 0;
  std::uint64_t data_bytes = 0;
};

SparseImage make_sparse_image(const fs::path& path, std::uint64_t size) {
  SparseImage img{path, size, 0};
  { std::ofstream(path, std::ios::binary); }
  fs::resize_file(path, size);
  const std::vector<std::pair<std::uint64_t, std::size_t>> pieces = {
      {0, 4096}, {1 << 20, 3 * 4096 + 100}, {5 << 20, 65536}, {size - 1000, 1000}};
  unsigned seed = 1;
  for (const auto& [offset, length] : pieces) {
    write_at(path, offset, random_bytes(length, seed++));
    img.data_bytes += length;
  }
  return img;
}

bool have_bmaptool() {
  return std::system("bmaptool --version >/dev/null 2>&1") == 0;
}

void bmaptool_create(const fs::path& image) {
  const std::string cmd = "bmaptool create -o '" + image.string() + ".bmap' '" + image.string() + "' 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
}

dentmark::flash::FlashOptions options(const fs::path& image, const fs::path& target) {
  dentmark::flash::FlashOptions o;
  o.image = image;
  o.target = target;
  return o;
}

SystemView no_mounts() {
  return SystemView{"", "", "/nonexistent-sysfs"};
}

}  // namespace

// ---- mountinfo ---------------------------------------------------------------------

TEST(FlashMountinfo, ParsesFieldsOptionalTagsAndOctalEscapes) {
  const std::string text =
      "22 1 8:2 / / rw,relatime shared:1 - ext4 /dev/sda2 rw,errors=remount-ro\n"
      "40 22 8:17 / /media/usb\\040stick rw,nosuid master:3 propagate_from:2 - vfat "
      "/dev/sdb1 rw\n"
      "51 22 0:45 / /proc rw - proc proc rw\n";
  const auto m = dentmark::flash::parse_mountinfo(text, "test");
  ASSERT_EQ(m.size(), 3u);
  EXPECT_EQ(m[0].major, 8u);
  EXPECT_EQ(m[0].minor, 2u);
  EXPECT_EQ(m[0].mount_point, "/");
  EXPECT_EQ(m[0].source, "/dev/sda2");
  EXPECT_EQ(m[1].mount_point, "/media/usb stick");
  EXPECT_EQ(m[1].fs_type, "vfat");
  EXPECT_EQ(m[1].source, "/dev/sdb1");
  EXPECT_EQ(m[2].major, 0u);
  EXPECT_EQ(m[2].minor, 45u);
}

TEST(FlashMountinfo, AMalformedLineIsNamed) {
  const std::string text = "22 1 8:2 / / rw - ext4 /dev/sda2 rw\nthis is not mountinfo\n";
  EXPECT_EQ(error_of([&] {
              dentmark::flash::parse_mountinfo(text, "/proc/self/mountinfo");
            }).rfind("/proc/self/mountinfo: line 2: not a mountinfo line", 0),
            0u);
}

TEST(FlashMountinfo, TheRealOneParses) {
  const auto view = SystemView::of_this_machine();
  const auto m = dentmark::flash::parse_mountinfo(view.mountinfo, "/proc/self/mountinfo");
  ASSERT_FALSE(m.empty());
  bool root = false;
  for (const auto& e : m) root = root || e.mount_point == "/";
  EXPECT_TRUE(root);
}

// ---- target checks -----------------------------------------------------------------

TEST(FlashTarget, NewAndExistingFilesAreAccepted) {
  dentmark::test::TempDir dir("flash");
  EXPECT_EQ(dentmark::flash::check_target(dir.path() / "new.img", no_mounts()), TargetKind::kNewFile);
  { std::ofstream(dir.path() / "old.img") << "x"; }
  EXPECT_EQ(dentmark::flash::check_target(dir.path() / "old.img", no_mounts()), TargetKind::kRegularFile);
  const std::string e =
      error_of([&] { dentmark::flash::check_target(dir.path() / "no-dir" / "x.img", no_mounts()); });
  EXPECT_NE(e.find("x.img: refused: its folder"), std::string::npos) << e;
}

TEST(FlashTarget, AFolderAndACharacterDeviceAreRefused) {
  dentmark::test::TempDir dir("flash");
  std::string e = error_of([&] { dentmark::flash::check_target(dir.path(), no_mounts()); });
  EXPECT_NE(e.find(dir.path().string() + ": refused: a folder"), std::string::npos) << e;
  e = error_of([&] { dentmark::flash::check_target("/dev/null", no_mounts()); });
  EXPECT_NE(e.find("/dev/null: refused: a character device"), std::string::npos) << e;
}

TEST(FlashTarget, AFileMountedAsAFilesystemIsRefused) {
  dentmark::test::TempDir dir("flash");
  const fs::path img = dir.path() / "disk.img";
  { std::ofstream(img) << "x"; }
  SystemView view = no_mounts();
  view.mountinfo =
      "22 1 8:2 / / rw - ext4 /dev/sda2 rw\n60 22 7:0 / /mnt/disk rw - ext4 " + img.string() + " rw\n";
  const std::string e = error_of([&] { dentmark::flash::check_target(img, view); });
  EXPECT_NE(e.find(img.string() + ": refused: it is mounted at /mnt/disk"), std::string::npos) << e;
}

// A block device this machine mounts: its root's when that is one (then said as
// such), else any other.
TEST(FlashTarget, AMountedBlockDeviceOfThisMachineIsRefused) {
  const auto view = SystemView::of_this_machine();
  auto mounts = dentmark::flash::parse_mountinfo(view.mountinfo, "mountinfo");
  std::stable_partition(mounts.begin(), mounts.end(), [](const auto& m) { return m.mount_point == "/"; });
  for (const auto& m : mounts) {
    struct stat st {};
    if (m.source.rfind("/dev/", 0) != 0 || ::stat(m.source.c_str(), &st) != 0 || !S_ISBLK(st.st_mode))
      continue;
    const std::string e = error_of([&] { dentmark::flash::check_target(m.source, view); });
    const std::string want =
        m.mount_point == "/" ? ": refused: it holds this machine's root filesystem" : ": refused:";
    EXPECT_NE(e.find(m.source + want), std::string::npos) << e;
    return;
  }
  GTEST_SKIP() << "no mount here has a block device node under /dev as its source";
}

// Block devices in a made-up sysfs: disk 'sdz' (250:0) with partitions sdz1 (250:1)
// and sdz2 (250:2); the device nodes are made with mknod in a temporary folder.
class FlashBlockTarget : public ::testing::Test {
 protected:
  void SetUp() override {
    const fs::path sys = dir_.path() / "sys";
    const fs::path disk = sys / "devices" / "virtual" / "block" / "sdz";
    fs::create_directories(disk / "holders");
    fs::create_directories(sys / "dev" / "block");
    fs::create_directories(sys / "block");
    fs::create_symlink("../../devices/virtual/block/sdz", sys / "dev" / "block" / "250:0");
    for (int p : {1, 2}) {
      const fs::path part = disk / ("sdz" + std::to_string(p));
      fs::create_directories(part / "holders");
      { std::ofstream(part / "partition") << p << "\n"; }
      fs::create_symlink("../../devices/virtual/block/sdz/sdz" + std::to_string(p),
                         sys / "dev" / "block" / ("250:" + std::to_string(p)));
    }
    view_ = SystemView{"", "", sys};
    for (int minor : {0, 1, 2}) {
      const fs::path node = dir_.path() / ("sdz" + (minor ? std::to_string(minor) : ""));
      if (::mknod(node.c_str(), S_IFBLK | 0600, ::makedev(250, minor)) != 0) {
        skip_ = "cannot make block device nodes here (mknod: " + std::string(std::strerror(errno)) + ")";
        return;
      }
    }
  }
  fs::path node(const std::string& name) const { return dir_.path() / name; }

  dentmark::test::TempDir dir_{"flash-blk"};
  SystemView view_;
  std::string skip_;
};

TEST_F(FlashBlockTarget, AnUnusedWholeDiskIsAccepted) {
  if (!skip_.empty()) GTEST_SKIP() << skip_;
  view_.mountinfo = "22 1 8:2 / / rw - ext4 /dev/sda2 rw\n";
  EXPECT_EQ(dentmark::flash::check_target(node("sdz"), view_), TargetKind::kBlockDevice);
}

TEST_F(FlashBlockTarget, ADiskWithAMountedPartitionIsRefused) {
  if (!skip_.empty()) GTEST_SKIP() << skip_;
  view_.mountinfo =
      "22 1 8:2 / / rw - ext4 /dev/sda2 rw\n"
      "61 22 250:2 / /media/stick rw - vfat /dev/sdz2 rw\n";
  const std::string e = error_of([&] { dentmark::flash::check_target(node("sdz"), view_); });
  EXPECT_NE(e.find("sdz: refused: /dev/sdz2 on it is mounted at /media/stick"), std::string::npos) << e;
}

TEST_F(FlashBlockTarget, TheHostsRootDiskIsRefusedAsSuch) {
  if (!skip_.empty()) GTEST_SKIP() << skip_;
  view_.mountinfo =
      "22 1 250:1 / / rw - ext4 /dev/sdz1 rw\n"
      "61 22 250:2 / /srv rw - ext4 /dev/sdz2 rw\n";
  const std::string e = error_of([&] { dentmark::flash::check_target(node("sdz"), view_); });
  EXPECT_NE(e.find("sdz: refused: it holds this machine's root filesystem"), std::string::npos) << e;
}

TEST_F(FlashBlockTarget, APartitionAndADeviceInUseByDeviceMapperAreRefused) {
  if (!skip_.empty()) GTEST_SKIP() << skip_;
  std::string e = error_of([&] { dentmark::flash::check_target(node("sdz1"), view_); });
  EXPECT_NE(e.find("sdz1: refused: it is partition sdz1 of /dev/sdz"), std::string::npos) << e;
  fs::create_directories(view_.sysfs / "devices/virtual/block/sdz/sdz2/holders/dm-0");
  e = error_of([&] { dentmark::flash::check_target(node("sdz"), view_); });
  EXPECT_NE(e.find("sdz: refused: sdz2 is in use by dm-0"), std::string::npos) << e;
}

// ---- block maps and flashing -------------------------------------------------------

class Flash : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!have_bmaptool()) GTEST_SKIP() << "bmaptool not installed (scripts/setup-deps)";
  }
  dentmark::test::TempDir dir_{"flash"};
};

TEST_F(Flash, ASparseImageIsWrittenToANewFileByteForByteAndVerified) {
  const auto img = make_sparse_image(dir_.path() / "edge.img", 64ull << 20);
  bmaptool_create(img.path);
  const auto map = dentmark::flash::read_bmap(img.path.string() + ".bmap");
  EXPECT_EQ(map.image_size, img.size);
  EXPECT_EQ(map.checksum_type, "sha256");
  // Mapped: whole 4 KiB blocks holding data (the last, partial one counted to the end).
  EXPECT_GE(map.mapped_bytes(), img.data_bytes);
  EXPECT_LE(map.mapped_bytes(), img.data_bytes + 4 * 2 * 4096);

  dentmark::flash::FlashOptions o;
  o.image = img.path;
  o.target = dir_.path() / "card.img";
  const auto r = dentmark::flash::flash_image(o, SystemView::of_this_machine());
  EXPECT_EQ(r.kind, TargetKind::kNewFile);
  EXPECT_EQ(r.bmap, fs::path(img.path.string() + ".bmap"));
  EXPECT_EQ(r.image_size, img.size);
  EXPECT_EQ(r.verified_bytes, map.mapped_bytes());
  EXPECT_EQ(fs::file_size(o.target), img.size);
  EXPECT_TRUE(read_file(o.target) == read_file(img.path));
  struct stat st {};
  ASSERT_EQ(::stat(o.target.c_str(), &st), 0);
  std::printf(
      "[ figures ] %.1f MiB image, %.1f KiB mapped: written in %.3f s, %.1f KiB verified "
      "in %.3f s; the file occupies %.1f KiB on disk\n",
      static_cast<double>(img.size) / (1 << 20), static_cast<double>(map.mapped_bytes()) / 1024,
      r.write_seconds, static_cast<double>(r.verified_bytes) / 1024, r.verify_seconds,
      static_cast<double>(st.st_blocks) * 512 / 1024);
  // Nothing else left in the folder (the temporary copy was renamed into place).
  int entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir_.path())) ++entries;
  EXPECT_EQ(entries, 3);  // edge.img, edge.img.bmap, card.img
}

TEST_F(Flash, AnExistingFileIsReplacedWhole) {
  const auto img = make_sparse_image(dir_.path() / "edge.img", 8ull << 20);
  bmaptool_create(img.path);
  const fs::path target = dir_.path() / "card.img";
  { std::ofstream(target, std::ios::binary) << random_bytes(12 << 20, 9); }
  auto o = options(img.path, target);
  const auto r = dentmark::flash::flash_image(o, SystemView::of_this_machine());
  EXPECT_EQ(r.kind, TargetKind::kRegularFile);
  EXPECT_EQ(fs::file_size(target), img.size);
  EXPECT_TRUE(read_file(target) == read_file(img.path));
}

TEST_F(Flash, ACorruptedImageFailsNamingItAndLeavesNoTarget) {
  const auto img = make_sparse_image(dir_.path() / "edge.img", 8ull << 20);
  bmaptool_create(img.path);
  write_at(img.path, (5 << 20) + 1234, "X");  // inside a mapped range, after the map was made
  auto o = options(img.path, dir_.path() / "card.img");
  const std::string e = error_of([&] { dentmark::flash::flash_image(o, SystemView::of_this_machine()); });
  EXPECT_EQ(e.rfind(img.path.string() + ": writing to " + o.target.string() + " failed: ", 0), 0u) << e;
  EXPECT_NE(e.find("checksum mismatch"), std::string::npos) << e;
  EXPECT_FALSE(fs::exists(o.target));
  int entries = 0;
  for ([[maybe_unused]] const auto& x : fs::directory_iterator(dir_.path())) ++entries;
  EXPECT_EQ(entries, 2);  // no temporary folder left behind
}

TEST_F(Flash, ACorruptedExistingTargetKeepsItsOldContent) {
  const auto img = make_sparse_image(dir_.path() / "edge.img", 8ull << 20);
  bmaptool_create(img.path);
  write_at(img.path, 100, "Y");
  const fs::path target = dir_.path() / "card.img";
  const std::string old = random_bytes(4096, 7);
  { std::ofstream(target, std::ios::binary) << old; }
  auto o = options(img.path, target);
  EXPECT_NE(error_of([&] { dentmark::flash::flash_image(o, SystemView::of_this_machine()); }), "(no error)");
  EXPECT_TRUE(read_file(target) == old);
}

TEST_F(Flash, ReadBackFindsAFlippedByteOnTheTarget) {
  const auto img = make_sparse_image(dir_.path() / "edge.img", 8ull << 20);
  bmaptool_create(img.path);
  const auto map = dentmark::flash::read_bmap(img.path.string() + ".bmap");
  const fs::path copy = dir_.path() / "copy.img";
  fs::copy_file(img.path, copy);
  EXPECT_EQ(dentmark::flash::verify_against_bmap(copy, map), map.mapped_bytes());
  write_at(copy, (1 << 20) + 5000, "Z");
  const std::string e = error_of([&] { dentmark::flash::verify_against_bmap(copy, map); });
  EXPECT_EQ(e.rfind(copy.string() + ": verification failed: blocks 256-259", 0), 0u) << e;
}

TEST_F(Flash, AnImageWithoutABlockMapIsRefusedUnlessNoBmap) {
  const auto img = make_sparse_image(dir_.path() / "edge.img", 8ull << 20);
  auto o = options(img.path, dir_.path() / "card.img");
  const std::string e = error_of([&] { dentmark::flash::flash_image(o, SystemView::of_this_machine()); });
  EXPECT_EQ(e.rfind(img.path.string() + ": no block map " + img.path.string() + ".bmap", 0), 0u) << e;
  EXPECT_FALSE(fs::exists(o.target));

  o.no_bmap = true;
  const auto r = dentmark::flash::flash_image(o, SystemView::of_this_machine());
  EXPECT_TRUE(r.bmap.empty());
  EXPECT_EQ(r.verified_bytes, img.size);  // every byte compared by SHA-256
  EXPECT_TRUE(read_file(o.target) == read_file(img.path));
}

TEST_F(Flash, AMountedTargetIsRefusedBeforeAnythingIsWritten) {
  const auto img = make_sparse_image(dir_.path() / "edge.img", 8ull << 20);
  bmaptool_create(img.path);
  const fs::path target = dir_.path() / "card.img";
  { std::ofstream(target) << "mounted"; }
  SystemView view = no_mounts();
  view.mountinfo = "60 22 7:3 / /mnt/card rw - ext4 " + target.string() + " rw\n";
  auto o = options(img.path, target);
  const std::string e = error_of([&] { dentmark::flash::flash_image(o, view); });
  EXPECT_NE(e.find(target.string() + ": refused: it is mounted at /mnt/card"), std::string::npos) << e;
  EXPECT_EQ(read_file(target), "mounted");
}
