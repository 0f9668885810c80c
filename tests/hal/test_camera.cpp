// Cameras: stereo pairing by timestamp, the V4L2 pixel conversion, the replay and
// simulated backends, and (where a kernel device exists) V4L2 streaming.
#include <gtest/gtest.h>
#include <linux/videodev2.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <regex>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/hal/camera/replay_camera.h"
#include "dentmark/firmware/hal/camera/sim_camera.h"
#include "dentmark/firmware/hal/camera/stereo_pairing.h"
#include "dentmark/firmware/hal/camera/v4l2_camera.h"

namespace dentmark::hal {
namespace {

namespace fs = std::filesystem;

Frame frame_at(double t, std::uint64_t seq = 0) {
  Frame f;
  f.time = t;
  f.sequence = seq;
  f.image = cv::Mat(2, 2, CV_8UC1, cv::Scalar(static_cast<double>(seq % 256)));
  return f;
}

TEST(StereoPairing, PairsWithinSkewAndCountsUnpairedFrames) {
  StereoPairing pairing(0.002);
  const double period = 1.0 / 30.0;
  for (int k = 0; k < 30; ++k) {
    pairing.push_left(frame_at(k * period, k));
    if (k != 5) pairing.push_right(frame_at(k * period + 0.001, k));  // right frame 5 lost
  }
  int n = 0;
  while (auto p = pairing.pop()) {
    EXPECT_EQ(p->left.sequence, p->right.sequence);
    EXPECT_NEAR(p->skew, 0.001, 1e-12);
    EXPECT_NEAR(p->time, p->left.time + 0.0005, 1e-12);
    EXPECT_NE(p->left.sequence, 5u);
    ++n;
  }
  EXPECT_EQ(n, 29);
  EXPECT_EQ(pairing.counters().pairs, 29);
  EXPECT_EQ(pairing.counters().dropped_left, 1);  // left 5 had no partner
  EXPECT_EQ(pairing.counters().dropped_right, 0);
}

TEST(StereoPairing, SkewBeyondTheLimitNeverPairs) {
  StereoPairing pairing(0.002);
  for (int k = 0; k < 10; ++k) {
    pairing.push_left(frame_at(k * 0.05));
    pairing.push_right(frame_at(k * 0.05 + 0.0021));
  }
  EXPECT_FALSE(pairing.pop().has_value());
  EXPECT_EQ(pairing.counters().pairs, 0);
  EXPECT_GE(pairing.counters().dropped_left, 9);
}

TEST(StereoPairing, TakesTheCloserOfTwoCandidates) {
  StereoPairing pairing(0.002);
  pairing.push_right(frame_at(-0.0015, 1));
  pairing.push_right(frame_at(0.0005, 2));
  pairing.push_left(frame_at(0.0, 7));
  const auto p = pairing.pop();
  ASSERT_TRUE(p.has_value());
  EXPECT_EQ(p->right.sequence, 2u);
  EXPECT_EQ(pairing.counters().dropped_right, 1);
}

TEST(StereoPairing, OutOfOrderFramesAndStalledSideAreBounded) {
  StereoPairing pairing(0.002, 4);
  pairing.push_left(frame_at(1.0));
  pairing.push_left(frame_at(0.5));  // older than its predecessor
  EXPECT_EQ(pairing.counters().dropped_left, 1);
  for (int k = 0; k < 10; ++k) pairing.push_left(frame_at(2.0 + k));  // right camera stalled
  EXPECT_EQ(pairing.counters().dropped_left, 1 + 11 - 4);
  EXPECT_THROW(StereoPairing(-1.0), CameraError);
}

TEST(V4l2Pixels, LumaFromPackedAndPlanarFormatsWithStridePadding) {
  const int w = 4, h = 3;
  const std::uint32_t stride = 2 * w + 6;  // padded rows
  std::vector<std::uint8_t> yuyv(stride * h, 0xEE);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      yuyv[y * stride + 2 * x] = static_cast<std::uint8_t>(10 * y + x);  // Y
      yuyv[y * stride + 2 * x + 1] = 128;                                // U or V
    }
  cv::Mat g = luma_from_buffer(yuyv.data(), yuyv.size(), V4L2_PIX_FMT_YUYV, w, h, stride);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) EXPECT_EQ(g.at<std::uint8_t>(y, x), 10 * y + x);
  // UYVY: luma at odd bytes.
  std::vector<std::uint8_t> uyvy(2 * w * h);
  for (int i = 0; i < w * h; ++i) {
    uyvy[2 * i] = 128;
    uyvy[2 * i + 1] = static_cast<std::uint8_t>(i);
  }
  g = luma_from_buffer(uyvy.data(), uyvy.size(), V4L2_PIX_FMT_UYVY, w, h, 0);
  EXPECT_EQ(g.at<std::uint8_t>(2, 3), 11);
  // NV12: the Y plane comes first; the chroma after it is ignored.
  std::vector<std::uint8_t> nv12(w * h * 3 / 2, 77);
  for (int i = 0; i < w * h; ++i) nv12[i] = static_cast<std::uint8_t>(200 - i);
  g = luma_from_buffer(nv12.data(), nv12.size(), V4L2_PIX_FMT_NV12, w, h, w);
  EXPECT_EQ(g.at<std::uint8_t>(1, 1), 200 - 5);
  // A short buffer (truncated frame) and an unknown format are errors, not garbage.
  EXPECT_THROW(luma_from_buffer(yuyv.data(), yuyv.size() - 7, V4L2_PIX_FMT_YUYV, w, h, stride), CameraError);
  EXPECT_THROW(luma_from_buffer(yuyv.data(), yuyv.size(), V4L2_PIX_FMT_MJPEG, w, h, stride), CameraError);
  EXPECT_EQ(fourcc_name(V4L2_PIX_FMT_YUYV), "YUYV");
}

TEST(V4l2Pixels, LumaFromPackedRgbIsBt601InBothByteOrders) {
  const int w = 5, h = 4;
  const std::uint32_t stride = 3 * w + 1;  // padded rows
  std::mt19937 rng(7);
  std::vector<std::uint8_t> rgb(stride * h, 0xEE);
  for (int y = 0; y < h; ++y)
    for (int i = 0; i < 3 * w; ++i) rgb[y * stride + i] = static_cast<std::uint8_t>(rng() % 256);
  std::vector<std::uint8_t> bgr = rgb;  // the same pixels with red and blue swapped
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) std::swap(bgr[y * stride + 3 * x], bgr[y * stride + 3 * x + 2]);
  const cv::Mat a = luma_from_buffer(rgb.data(), rgb.size(), V4L2_PIX_FMT_RGB24, w, h, stride);
  const cv::Mat b = luma_from_buffer(bgr.data(), bgr.size(), V4L2_PIX_FMT_BGR24, w, h, stride);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::uint8_t* p = &rgb[y * stride + 3 * x];
      const double luma = 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];  // ITU-R BT.601
      EXPECT_NEAR(a.at<std::uint8_t>(y, x), luma, 1.0) << x << "," << y;
      EXPECT_EQ(a.at<std::uint8_t>(y, x), b.at<std::uint8_t>(y, x));
    }
  EXPECT_THROW(luma_from_buffer(rgb.data(), stride * (h - 1) + 3 * w - 1, V4L2_PIX_FMT_RGB24, w, h, stride),
               CameraError);
}

TEST(V4l2Camera, NonDeviceGivesAClearError) {
  V4l2Camera cam("/dev/null", {640, 480});
  try {
    cam.start();
    FAIL();
  } catch (const CameraError& e) {
    EXPECT_NE(std::string(e.what()).find("/dev/null"), std::string::npos) << e.what();
  }
}

// Streams from a real capture node (vivid in the QEMU tier) when one exists.
TEST(V4l2Camera, StreamsFromAKernelDevice) {
  std::string device;
  if (const char* env = std::getenv("DENTMARK_V4L2_DEVICE")) device = env;
  if (device.empty() && fs::exists("/dev/video0")) device = "/dev/video0";
  if (device.empty()) GTEST_SKIP() << "no V4L2 device (set DENTMARK_V4L2_DEVICE; vivid in the QEMU tier)";
  V4l2Camera cam(device, {640, 480});
  try {
    cam.start();
  } catch (const CameraError& e) {
    GTEST_SKIP() << "device present but not a usable capture node: " << e.what();
  }
  double last = -1;
  for (int i = 0; i < 5; ++i) {
    const auto f = cam.grab(2.0);
    ASSERT_TRUE(f.has_value()) << "no frame within 2 s";
    EXPECT_EQ(f->image.size(), cv::Size(640, 480));
    EXPECT_GT(f->time, last);
    last = f->time;
  }
  cam.stop();
}

class ReplayFolder : public ::testing::Test {
 protected:
  void SetUp() override {
    char tmpl[] = "/tmp/dentmark-replay-XXXXXX";
    ASSERT_NE(::mkdtemp(tmpl), nullptr);
    dir = tmpl;
    std::ofstream csv(dir / "frames.csv");
    csv << "index,t,left,right\n";
    for (int k = 0; k < 3; ++k) {
      const std::string l = "L" + std::to_string(k) + ".png", r = "R" + std::to_string(k) + ".png";
      cv::imwrite((dir / l).string(), cv::Mat(24, 32, CV_8UC1, cv::Scalar(10 + k)));
      cv::imwrite((dir / r).string(), cv::Mat(24, 32, CV_8UC3, cv::Scalar(100 + k, 100 + k, 100 + k)));
      csv << k << "," << 5.0 + 0.1 * k << "," << l << "," << r << "\n";
    }
  }
  void TearDown() override { fs::remove_all(dir); }
  fs::path dir;
};

TEST_F(ReplayFolder, ReplaysOneSideAtItsRecordedPace) {
  clock::SimClock c(0.0, 100.0);
  ReplayCamera left(dir, StereoSide::kLeft, c), right(dir, StereoSide::kRight, c);
  EXPECT_EQ(left.size(), cv::Size(32, 24));
  StereoCamera stereo(left, right, 0.002, c);
  stereo.start();
  for (int k = 0; k < 3; ++k) {
    const auto p = stereo.grab_pair(1.0);
    ASSERT_TRUE(p.has_value()) << k;
    EXPECT_EQ(p->left.sequence, static_cast<std::uint64_t>(k));
    EXPECT_EQ(p->left.image.at<std::uint8_t>(0, 0), 10 + k);
    EXPECT_EQ(p->right.image.at<std::uint8_t>(3, 3), 100 + k);  // colour read as grey
    EXPECT_NEAR(p->time, 100.0 + 0.1 * k, 1e-9);                // recorded pace on the injected clock
    EXPECT_DOUBLE_EQ(p->skew, 0.0);
  }
  EXPECT_FALSE(stereo.grab_pair(0.1).has_value());
  EXPECT_TRUE(left.exhausted());
  EXPECT_GE(c.now(), 100.2);
}

TEST_F(ReplayFolder, BadIndexNamesFileAndLine) {
  std::ofstream(dir / "frames.csv") << "index,t,left,right\n0,1.0,L0.png,R0.png\n1,0.9,L1.png,R1.png\n";
  clock::SimClock c;
  try {
    ReplayCamera cam(dir, StereoSide::kLeft, c);
    FAIL();
  } catch (const CameraError& e) {
    EXPECT_NE(std::string(e.what()).find("frames.csv:3: t must increase"), std::string::npos) << e.what();
  }
  std::ofstream(dir / "frames.csv") << "index,time,left,right\n";
  EXPECT_THROW(ReplayCamera(dir, StereoSide::kLeft, c), CameraError);
  std::ofstream(dir / "frames.csv") << "index,t,left,right\n0,1.0,missing.png,R0.png\n";
  try {
    ReplayCamera cam(dir, StereoSide::kLeft, c);
    FAIL();
  } catch (const CameraError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.png"), std::string::npos) << e.what();
  }
}

TEST(SimCamera, StereoPairFromTwoSimulatedSensorsWithSkew) {
  clock::SimClock c(20.0);
  const auto value = [](double t) { return static_cast<int>(std::fmod(std::floor(t * 100.0), 256.0)); };
  const auto render = [&](double t) { return cv::Mat(8, 8, CV_8UC1, cv::Scalar(value(t))); };
  SimCamera left("sim:camL", {8, 8}, 1.0 / 30.0, render, c, 0.0, 20);
  SimCamera right("sim:camR", {8, 8}, 1.0 / 30.0, render, c, 0.0012, 20);
  StereoCamera stereo(left, right, 0.002, c);
  stereo.start();
  int n = 0;
  while (auto p = stereo.grab_pair(1.0)) {
    EXPECT_NEAR(p->skew, 0.0012, 1e-9);
    EXPECT_EQ(p->left.sequence, p->right.sequence);
    EXPECT_EQ(p->left.image.at<std::uint8_t>(0, 0), value(p->left.time));
    ++n;
  }
  // Both start on the same frame grid; if a grid point falls between the two start()
  // calls, one frame of one side has no partner (counted).
  EXPECT_GE(n, 19);
  EXPECT_LE(stereo.counters().dropped_left + stereo.counters().dropped_right, 1);
}

TEST(SimCamera, SensorsOutOfSyncGiveNoPairsButCounts) {
  clock::SimClock c(20.0);
  const auto render = [](double) { return cv::Mat(8, 8, CV_8UC1, cv::Scalar(0)); };
  SimCamera left("sim:camL", {8, 8}, 0.05, render, c, 0.0, 10);
  SimCamera right("sim:camR", {8, 8}, 0.05, render, c, 0.01, 10);  // 10 ms apart
  StereoCamera stereo(left, right, 0.002, c);
  stereo.start();
  EXPECT_FALSE(stereo.grab_pair(2.0).has_value());
  EXPECT_EQ(stereo.counters().pairs, 0);
  EXPECT_GE(stereo.counters().dropped_left + stereo.counters().dropped_right, 9);
}

}  // namespace
}  // namespace dentmark::hal

namespace dentmark::hal {
namespace {

// Property: any corruption of frames.csv either parses into strictly increasing
// frames or fails with one CameraError naming frames.csv and a line, never a crash.
TEST_F(ReplayFolder, CorruptedIndexNeverCrashes) {
  std::string good;
  {
    std::ifstream in(dir / "frames.csv");
    good.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  std::mt19937 rng(11);
  const std::string alphabet = "0123456789.,-+eE \r\nnaNinfxLR/";
  int parsed = 0, rejected = 0;
  for (int trial = 0; trial < 400; ++trial) {
    std::string text = good;
    const int edits = 1 + static_cast<int>(rng() % 4);
    for (int e = 0; e < edits && !text.empty(); ++e) {
      const std::size_t pos = rng() % text.size();
      switch (rng() % 3) {
        case 0:
          text[pos] = alphabet[rng() % alphabet.size()];
          break;
        case 1:
          text.erase(pos, 1 + rng() % 3);
          break;
        default:
          text.insert(pos, 1, alphabet[rng() % alphabet.size()]);
      }
    }
    std::ofstream(dir / "frames.csv", std::ios::trunc) << text;
    try {
      const auto entries = read_replay_index(dir, StereoSide::kLeft);
      ASSERT_FALSE(entries.empty());
      for (std::size_t i = 1; i < entries.size(); ++i) ASSERT_GT(entries[i].t, entries[i - 1].t);
      ++parsed;
    } catch (const CameraError& err) {
      ASSERT_TRUE(std::regex_search(std::string(err.what()), std::regex(R"(frames\.csv:\d+: )")))
          << err.what();
      ++rejected;
    }
  }
  EXPECT_GT(rejected, 0);
  EXPECT_GT(parsed, 0);  // harmless edits (e.g. in a file name) still parse
}

}  // namespace
}  // namespace dentmark::hal
