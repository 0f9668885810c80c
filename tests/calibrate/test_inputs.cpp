// Command inputs: the target option parser, image pairing, the inputs' digest.
#include <gtest/gtest.h>

#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "../support/temp_dir.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"
#include "dentmark/firmware/calibrate/input_digest.h"
#include "dentmark/firmware/calibrate/stereo_from_images.h"

namespace dentmark::calibrate {
namespace {

namespace fs = std::filesystem;

template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const CalibrateError& e) {
    return e.what();
  }
  return "(no error)";
}

void touch(const fs::path& p, const std::string& bytes = "x") {
  std::ofstream(p, std::ios::binary) << bytes;
}

TEST(TargetOption, ParsesAndRefuses) {
  const TargetSpec c = parse_target("chessboard:9x6", 0.025, 0, "");
  EXPECT_EQ(c.kind, TargetKind::kChessboard);
  EXPECT_EQ(c.corner_count(), 54);
  EXPECT_EQ(c.corner(10), cv::Point3f(0.025f, 0.025f, 0.0f));
  EXPECT_EQ(c.describe(), "chessboard:9x6 square 0.025 m");
  const TargetSpec a = parse_target("charuco:7x5", 0.04, 0.03, "DICT_4X4_50");
  EXPECT_EQ(a.corner_count(), 24);
  EXPECT_EQ(a.corner(0), cv::Point3f(0.04f, 0.04f, 0.0f));
  EXPECT_EQ(error_of([] { parse_target("chess:9x6", 0.025, 0, ""); }),
            "--pattern: 'chess:9x6' is not chessboard:COLSxROWS or charuco:COLSxROWS");
  EXPECT_EQ(
      error_of([] { parse_target("chessboard:7x7", 0.025, 0, ""); }),
      "--pattern: a square chessboard (chessboard:7x7) has no defined orientation; use one with different "
      "counts, e.g. 9x6");
  EXPECT_EQ(error_of([] { parse_target("chessboard:9x6", -1, 0, ""); }),
            "--square: -1 m is not a square size (0 < s < 1 m)");
  EXPECT_EQ(error_of([] { parse_target("charuco:7x5", 0.04, 0.05, "DICT_4X4_50"); }),
            "--marker: 0.05 m must be positive and smaller than --square");
  EXPECT_EQ(error_of([] { parse_target("charuco:7x5", 0.04, 0.03, "DICT_4x4_50"); }),
            "--dictionary: 'DICT_4x4_50' is not an OpenCV predefined dictionary (e.g. DICT_5X5_100)");
  EXPECT_EQ(error_of([] { parse_target("charuco:12x10", 0.02, 0.015, "DICT_4X4_50"); }),
            "--dictionary: DICT_4X4_50 has 50 markers; a 12x10 board needs 60");
}

TEST(ImagePairs, PairsByNumberAndIgnoresOtherFiles) {
  ::dentmark::test::TempDir d("calib-pairs");
  touch(d.path() / "left1.png");
  touch(d.path() / "right01.png");
  touch(d.path() / "LEFT10.JPG");
  touch(d.path() / "right10.jpg");
  touch(d.path() / "left.jpg");  // no number: not a pair member
  touch(d.path() / "notes.txt");
  const auto pairs = find_image_pairs(d.path());
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_EQ(pairs[0].number, 1);
  EXPECT_EQ(pairs[0].right.filename(), "right01.png");
  EXPECT_EQ(pairs[1].name, "10");
}

TEST(ImagePairs, RefusesEmptyUnpairedAndDuplicate) {
  ::dentmark::test::TempDir d("calib-pairs-bad");
  EXPECT_EQ(error_of([&] { find_image_pairs(d.path()); }),
            d.path().string() +
                ": no image pairs (expected left<N>.<ext> and right<N>.<ext>, ext png, jpg or jpeg)");
  EXPECT_EQ(error_of([&] { find_image_pairs(d.path() / "nope"); }),
            (d.path() / "nope").string() + ": not a directory");
  touch(d.path() / "left03.png");
  EXPECT_EQ(error_of([&] { find_image_pairs(d.path()); }),
            (d.path() / "left03.png").string() + ": no right image numbered 3 to pair with");
  touch(d.path() / "right3.png");
  touch(d.path() / "right03.png");
  EXPECT_EQ(error_of([&] { find_image_pairs(d.path()); }),
            d.path().string() + ": right03.png and right3.png both carry right image number 3");
}

TEST(ImagePairs, RefusesImagesOfDifferentSizes) {
  ::dentmark::test::TempDir d("calib-sizes");
  for (int i = 1; i <= 6; ++i) {
    const std::string n = "0" + std::to_string(i);
    cv::imwrite((d.path() / ("left" + n + ".png")).string(), cv::Mat(480, 640, CV_8UC1, cv::Scalar(0)));
    cv::imwrite((d.path() / ("right" + n + ".png")).string(),
                cv::Mat(i == 4 ? 240 : 480, i == 4 ? 320 : 640, CV_8UC1, cv::Scalar(0)));
  }
  const TargetSpec t = parse_target("chessboard:9x6", 0.025, 0, "");
  EXPECT_EQ(error_of([&] { calibrate_stereo_images(d.path(), t); }),
            (d.path() / "right04.png").string() + ": 320x240 pixels, but left01.png has 640x480");
  cv::imwrite((d.path() / "right04.png").string(), cv::Mat(480, 640, CV_8UC1, cv::Scalar(0)));
  touch(d.path() / "left05.png", "not an image");
  EXPECT_EQ(error_of([&] { calibrate_stereo_images(d.path(), t); }),
            (d.path() / "left05.png").string() + ": not a readable image");
}

TEST(InputDigest, Sha256OfSettingsAndFiles) {
  // FIPS 180-2 test vector: SHA-256("abc").
  EXPECT_EQ(inputs_sha256("abc", {}), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  ::dentmark::test::TempDir d("calib-digest");
  touch(d.path() / "a.png", "one");
  touch(d.path() / "b.png", "two");
  const std::string base = inputs_sha256("s", {d.path() / "a.png", d.path() / "b.png"});
  EXPECT_NE(base, inputs_sha256("s", {d.path() / "b.png", d.path() / "a.png"}));  // order
  EXPECT_NE(base, inputs_sha256("t", {d.path() / "a.png", d.path() / "b.png"}));  // settings
  touch(d.path() / "b.png", "twO");
  EXPECT_NE(base, inputs_sha256("s", {d.path() / "a.png", d.path() / "b.png"}));  // content
  EXPECT_EQ(error_of([&] { inputs_sha256("s", {d.path() / "c.png"}); }),
            (d.path() / "c.png").string() + ": cannot read");
}

}  // namespace
}  // namespace dentmark::calibrate
