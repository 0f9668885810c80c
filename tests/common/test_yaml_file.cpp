// files::open_yaml: a FileStorage YAML file opens and reads; a missing file, a folder and
// a broken file are refused with the file named and, for a broken one, its line.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "../support/temp_dir.h"
#include "dentmark/common/yaml_file.h"

namespace dentmark::files {
namespace {

namespace fs = std::filesystem;

// The message open_yaml throws for path ("" when it opens).
std::string problem_of(const fs::path& path) {
  try {
    open_yaml(path);
  } catch (const FileError& e) {
    return e.what();
  }
  return "";
}

struct Problem : std::runtime_error {
  using std::runtime_error::runtime_error;
};

TEST(YamlFile, OpensWhatFileStorageWroteAndReadsItsFields) {
  test::TempDir dir("yaml");
  const fs::path file = dir.path() / "rig.yaml";
  {
    cv::FileStorage out(file.string(), cv::FileStorage::WRITE);
    out << "image_width" << 1280 << "baseline_m" << 0.12;
  }
  cv::FileStorage in = open_yaml(file);
  EXPECT_EQ(static_cast<int>(in["image_width"]), 1280);
  EXPECT_DOUBLE_EQ(static_cast<double>(in["baseline_m"]), 0.12);
}

TEST(YamlFile, AMissingFileOrAFolderIsNoSuchFile) {
  test::TempDir dir("yaml");
  EXPECT_EQ(problem_of(dir.path() / "nope.yaml"), (dir.path() / "nope.yaml").string() + ": no such file");
  EXPECT_EQ(problem_of(dir.path()), dir.path().string() + ": no such file");
}

TEST(YamlFile, ABrokenFileIsNamedWithTheLineOfTheProblem) {
  test::TempDir dir("yaml");
  const fs::path file = dir.path() / "broken.yaml";
  std::ofstream(file) << "%YAML:1.0\n---\nimage_width: 1280\nK1: !!opencv-matrix\n  rows: [3\n";
  const std::string e = problem_of(file);
  EXPECT_EQ(e.rfind(file.string() + ": not readable as OpenCV FileStorage YAML (line ", 0), 0u) << e;
}

TEST(YamlFile, AModulesOwnErrorCarriesTheSameMessage) {
  test::TempDir dir("yaml");
  const fs::path missing = dir.path() / "stereo.yaml";
  try {
    open_yaml_or_throw<Problem>(missing);
    FAIL() << "no error";
  } catch (const Problem& e) {
    EXPECT_EQ(std::string(e.what()), missing.string() + ": no such file");
  }
}

}  // namespace
}  // namespace dentmark::files
