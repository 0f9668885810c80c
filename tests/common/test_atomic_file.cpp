// files::write_atomically and write_atomically_with: the target is either the old file
// or the whole new one; a failed write leaves the old file and no temporary behind.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>

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
