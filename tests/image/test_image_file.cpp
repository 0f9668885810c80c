// Grey images by content (PNG or JPEG), checked against OpenCV's imread(GRAYSCALE) as
// an independent peer: the real opencv-doc JPEGs and colour and 16-bit PNGs give the
// same pixels; damaged and unknown files are refused naming the file.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "dentmark/common/image/image_file.h"
#include "dentmark/common/image/png_io.h"

namespace dentmark::image {
namespace {

namespace fs = std::filesystem;

const fs::path kOpenCvData = "/usr/share/doc/opencv-doc/examples/data";

fs::path temp(const std::string& name) {
  return fs::temp_directory_path() / ("dentmark_image_file_" + std::to_string(::getpid()) + "_" + name);
}

double max_difference(const cv::Mat& a, const cv::Mat& b) {
  if (a.type() != b.type() || a.size() != b.size()) return 1e9;
  return cv::norm(a, b, cv::NORM_INF);
}

TEST(ImageFile, RealJpegsReadAsOpenCVReadsThem) {
  int read = 0;
  for (const char* name : {"left01.jpg", "right01.jpg", "left14.jpg", "lena.jpg", "baboon.jpg"}) {
    const fs::path p = kOpenCvData / name;
    if (!fs::exists(p)) continue;
    const cv::Mat ours = read_grey_image(p.string());
    const cv::Mat theirs = cv::imread(p.string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(theirs.empty()) << p;
    EXPECT_EQ(ours.type(), CV_8UC1) << p;
    EXPECT_EQ(max_difference(ours, theirs), 0.0) << p;
    ++read;
  }
  if (read == 0)
    GTEST_SKIP() << kOpenCvData << ": no opencv-doc images (install opencv-doc: scripts/setup-deps)";
  EXPECT_GE(read, 3);
}

TEST(ImageFile, ColourAnd16BitPngsReadAsOpenCVReadsThem) {
  cv::RNG rng(7);
  for (int type : {CV_8UC1, CV_8UC3, CV_16UC1, CV_16UC3}) {
    cv::Mat img(41, 59, type);
    rng.fill(img, cv::RNG::UNIFORM, 0, CV_MAT_DEPTH(type) == CV_16U ? 65536 : 256);
    const fs::path p = temp("img.png");
    write_png(p.string(), img);
    const cv::Mat ours = read_grey_image(p.string());
    EXPECT_EQ(ours.type(), CV_8UC1) << type;
    EXPECT_EQ(max_difference(ours, cv::imread(p.string(), cv::IMREAD_GRAYSCALE)), 0.0) << type;
    fs::remove(p);
  }
}

TEST(ImageFile, TheContentDecidesNotTheName) {
  cv::Mat img(16, 24, CV_8UC1, cv::Scalar(77));
  const fs::path png_named_jpg = temp("really_a_png.jpg");
  write_png(png_named_jpg.string(), img);
  EXPECT_EQ(max_difference(read_grey_image(png_named_jpg.string()), img), 0.0);
  fs::remove(png_named_jpg);
}

std::string error_of(const fs::path& p) {
  try {
    read_grey_image(p.string());
  } catch (const ImageError& e) {
    return e.what();
  }
  return "no error";
}

TEST(ImageFile, DamagedAndUnknownFilesAreRefusedNamingTheFile) {
  const fs::path missing = temp("missing.png");
  EXPECT_NE(error_of(missing).find(missing.string() + ": cannot open"), std::string::npos);

  const fs::path text = temp("notes.jpg");
  std::ofstream(text) << "P2\n2 2\n255\n0 1 2 3\n";  // a PGM: neither PNG nor JPEG
  EXPECT_NE(error_of(text).find(text.string() + ": neither a PNG nor a JPEG"), std::string::npos)
      << error_of(text);
  fs::remove(text);

  const fs::path real = kOpenCvData / "left01.jpg";
  if (!fs::exists(real)) GTEST_SKIP() << real << ": install opencv-doc";
  std::ifstream in(real, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const fs::path cut = temp("cut.jpg");
  // Cut in the middle of the image data: libjpeg decodes the rest as grey and warns.
  std::ofstream(cut, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size() / 2));
  std::string e = error_of(cut);
  EXPECT_NE(e.find(cut.string() + ": damaged JPEG"), std::string::npos) << e;
  // Cut inside the header: no image at all.
  std::ofstream(cut, std::ios::binary).write(bytes.data(), 40);
  e = error_of(cut);
  EXPECT_NE(e.find(cut.string() + ": not a readable JPEG"), std::string::npos) << e;
  fs::remove(cut);
}

}  // namespace
}  // namespace dentmark::image
