// PNG read/write through libpng, checked against OpenCV's imgcodecs as an independent
// peer, and against damaged files.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>

#include "dentmark/common/image/png_io.h"

namespace dentmark::image {
namespace {

namespace fs = std::filesystem;

fs::path temp(const std::string& name) {
  return fs::temp_directory_path() / ("dentmark_png_" + std::to_string(::getpid()) + "_" + name);
}

cv::Mat random_image(int type, int seed) {
  cv::Mat m(37, 53, type);  // odd sizes: no row padding luck
  cv::RNG rng(static_cast<std::uint64_t>(seed));
  rng.fill(m, cv::RNG::UNIFORM, 0, CV_MAT_DEPTH(type) == CV_16U ? 65536 : 256);
  return m;
}

bool same(const cv::Mat& a, const cv::Mat& b) {
  return a.type() == b.type() && a.size() == b.size() && cv::norm(a, b, cv::NORM_INF) == 0.0;
}

TEST(PngIo, RoundTripsEveryTypeAndAgreesWithOpenCV) {
  int seed = 1;
  for (int type : {CV_8UC1, CV_8UC3, CV_16UC1, CV_16UC3}) {
    const cv::Mat img = random_image(type, seed++);
    const fs::path ours = temp("ours.png"), theirs = temp("theirs.png");
    write_png(ours.string(), img);
    EXPECT_TRUE(same(read_png(ours.string()), img)) << type;
    // The peer reads what we wrote, and we read what the peer wrote.
    EXPECT_TRUE(same(cv::imread(ours.string(), cv::IMREAD_UNCHANGED), img)) << type;
    ASSERT_TRUE(cv::imwrite(theirs.string(), img));
    EXPECT_TRUE(same(read_png(theirs.string()), img)) << type;
    fs::remove(ours);
    fs::remove(theirs);
  }
}

TEST(PngIo, AlphaIsDroppedAndBilevelIsExpanded) {
  cv::Mat bgra = random_image(CV_8UC4, 9);
  const fs::path p = temp("bgra.png");
  ASSERT_TRUE(cv::imwrite(p.string(), bgra));
  cv::Mat bgr;
  cv::extractChannel(bgra, bgr, 0);
  const cv::Mat back = read_png(p.string());
  ASSERT_EQ(back.type(), CV_8UC3);
  std::vector<cv::Mat> planes;
  cv::split(back, planes);
  EXPECT_TRUE(same(planes[0], bgr));
  cv::Mat bw = random_image(CV_8UC1, 10) > 128;
  ASSERT_TRUE(cv::imwrite(p.string(), bw, {cv::IMWRITE_PNG_BILEVEL, 1}));
  const cv::Mat grey = read_png(p.string());
  ASSERT_EQ(grey.type(), CV_8UC1);
  EXPECT_TRUE(same(grey, bw));
  fs::remove(p);
}

TEST(PngIo, DamagedFilesGiveAnErrorNamingTheFile) {
  const fs::path p = temp("damaged.png");
  write_png(p.string(), random_image(CV_8UC3, 3));
  std::string bytes;
  {
    std::ifstream in(p, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  auto expect_error = [&](const std::string& content, const char* what) {
    {
      std::ofstream out(p, std::ios::binary | std::ios::trunc);
      out << content;
    }
    try {
      (void)read_png(p.string());
      ADD_FAILURE() << what << ": no error";
    } catch (const ImageError& e) {
      EXPECT_NE(std::string(e.what()).find(p.string()), std::string::npos) << e.what();
    }
  };
  expect_error("", "empty");
  expect_error("not a png at all", "text");
  expect_error(bytes.substr(0, 40), "cut in the header");
  expect_error(bytes.substr(0, bytes.size() / 2), "cut in the data");
  std::mt19937 rng(4);
  for (int i = 0; i < 200; ++i) {  // random corruption: an error or an image, never a crash
    std::string b = bytes;
    for (int k = 0; k < 4; ++k) b[8 + rng() % (b.size() - 8)] = static_cast<char>(rng());
    {
      std::ofstream out(p, std::ios::binary | std::ios::trunc);
      out << b;
    }
    try {
      (void)read_png(p.string());
    } catch (const ImageError&) {
    }
  }
  EXPECT_THROW(read_png((p.string() + ".missing")), ImageError);
  EXPECT_THROW(write_png(p.string(), cv::Mat(4, 4, CV_32FC1)), ImageError);
  EXPECT_THROW(write_png("/nonexistent-dir/x.png", random_image(CV_8UC1, 1)), ImageError);
  fs::remove(p);
}

}  // namespace
}  // namespace dentmark::image
