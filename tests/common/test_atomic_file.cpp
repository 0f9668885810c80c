// files::write_atomically and write_atomically_with: the target is either the old file
// or the whole new one; a failed write leaves the old file and no temporary behind.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <future>
#include <stdexcept>
#include <string>

#include "../support/temp_dir.h"
#include "dentmark/common/atomic_file.h"

namespace dentmark::files {
namespace {

namespace fs = std::filesystem;

std::size_t entries(const fs::path& dir) {
  return static_cast<std::size_t>(std::distance(fs::directory_iterator(dir), fs::directory_iterator()));
}

TEST(AtomicFile, ReplacesTheWholeFile) {
  test::TempDir dir("atomic");
  const fs::path target = dir.path() / "list.dml";
  write_atomically(target, std::string(100000, 'a'));
  write_atomically(target, "short");
  EXPECT_EQ(read_all(target), "short");
  EXPECT_EQ(entries(dir.path()), 1u);
}

TEST(AtomicFile, AFailingWriterLeavesTheOldFileAndNoTemporary) {
  test::TempDir dir("atomic");
  const fs::path target = dir.path() / "model.yaml";
  write_atomically(target, "old");
  EXPECT_THROW(write_atomically_with(target,
                                     [](const fs::path& tmp) {
                                       std::ofstream(tmp) << "half of the new";
                                       throw std::runtime_error("writer failed");
                                     }),
               std::runtime_error);
  EXPECT_EQ(read_all(target), "old");
  EXPECT_EQ(entries(dir.path()), 1u);
}

TEST(AtomicFile, TheWriterGetsATemporaryBesideTheTargetWithItsExtension) {
  test::TempDir dir("atomic");
  const fs::path target = dir.path() / "picture.png";
  fs::path seen;
  write_atomically_with(target, [&](const fs::path& tmp) {
    seen = tmp;
    std::ofstream(tmp) << "new";
  });
  EXPECT_EQ(seen.parent_path(), dir.path());
  EXPECT_EQ(seen.extension(), ".png");
  EXPECT_NE(seen, target);
  EXPECT_FALSE(fs::exists(seen));
  EXPECT_EQ(read_all(target), "new");
}

// What a reader of the pipe at `path` gets, read on another thread.
std::future<std::string> read_pipe(const fs::path& path) {
  return std::async(std::launch::async, [path] {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  });
}

// The reader's text; when nothing wrote to the pipe within 5 s, the reader is let go
// (an empty write end) and gets nothing.
std::string read_text(std::future<std::string>& reader, const fs::path& path) {
  if (reader.wait_for(std::chrono::seconds(5)) != std::future_status::ready)
    if (const int fd = ::open(path.c_str(), O_WRONLY | O_NONBLOCK); fd >= 0) ::close(fd);
  return reader.get();
}

TEST(AtomicFile, APipeOrALinkToOneIsWrittenInPlaceAndStaysAPipe) {
  // A rename over a device or a pipe would put a plain file in its place (as root, a
  // "--out /dev/null" once replaced /dev/null).
  test::TempDir dir("atomic");
  const fs::path fifo = dir.path() / "out.dml", link = dir.path() / "stdout";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  fs::create_symlink(fifo, link);
  std::future<std::string> got = read_pipe(fifo);
  write_atomically(link, "defects");
  EXPECT_EQ(read_text(got, fifo), "defects");
  got = read_pipe(fifo);
  write_atomically_with(fifo, [](const fs::path& p) { std::ofstream(p, std::ios::binary) << "report"; });
  EXPECT_EQ(read_text(got, fifo), "report");
  EXPECT_TRUE(fs::is_fifo(fifo));
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_EQ(entries(dir.path()), 2u);  // no temporary left beside them
}

TEST(AtomicFile, AMissingFolderIsAnErrorNamingTheFile) {
  test::TempDir dir("atomic");
  const fs::path target = dir.path() / "absent" / "x.json";
  try {
    write_atomically(target, "x");
    FAIL() << "no error";
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find(target.string()), std::string::npos) << e.what();
  }
  try {
    write_atomically_with(target, [](const fs::path& tmp) {
      std::ofstream out(tmp);
      if (!out) throw FileError(tmp, "cannot create");
    });
    FAIL() << "no error";
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find("absent"), std::string::npos) << e.what();
  }
}

TEST(AppendLog, EveryAppendedLineIsThere) {
  test::TempDir dir("atomic");
  {
    AppendLog log(dir.path() / "journal");
    log.append("spray 1");
    log.append("mark 1");
  }
  AppendLog again(dir.path() / "journal");
  again.append("end");
  EXPECT_EQ(read_all(dir.path() / "journal"), "spray 1\nmark 1\nend\n");
}

}  // namespace
}  // namespace dentmark::files
