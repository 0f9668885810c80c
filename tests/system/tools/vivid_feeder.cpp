// Feeds a rendered stereo sequence (`dentmark synth stereo`: the moving door) into two
// V4L2 video output devices in real time, frame k at its time t_k after the start on
// CLOCK_MONOTONIC. In the system-test guest these are the HDMI outputs of two vivid
// instances whose video loops back to their captures, so the edge daemon reads the
// rendered frames through its own V4L2 mmap capture path (docs/system-tests.md).
//
// vivid keeps showing an output buffer until the next one is queued, so the door
// stands still at its last frame once the sequence ends (the line stopped); the
// program keeps streaming until SIGTERM or SIGINT. Every frame is decoded into memory
// before the clock starts.
//
// Usage: vivid_feeder SEQUENCE_DIR LEFT_OUTPUT_DEVICE RIGHT_OUTPUT_DEVICE
// Prints one line when streaming starts and a summary at the end; exit 0, or 1 with
// the reason.
#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <signal.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "dentmark/firmware/track/sequence.h"

namespace {

volatile sig_atomic_t g_stop = 0;
void on_signal(int) {
  g_stop = 1;
}

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

int xioctl(int fd, unsigned long request, void* arg) {
  int r;
  do {
    r = ::ioctl(fd, request, arg);
  } while (r < 0 && errno == EINTR);
  return r;
}

// One V4L2 video output with mmap buffers, 8-bit grey frames of a fixed size.
class GreyOutput {
 public:
  GreyOutput(const std::string& device, cv::Size size) : device_(device), size_(size) {
    fd_ = ::open(device.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
    if (fd_ < 0) fail("open");
    v4l2_format fmt{};
    fmt.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    fmt.fmt.pix.width = static_cast<std::uint32_t>(size.width);
    fmt.fmt.pix.height = static_cast<std::uint32_t>(size.height);
    fmt.fmt.pix.pixelformat = V4L2_PIX_FMT_GREY;
    fmt.fmt.pix.field = V4L2_FIELD_NONE;
    if (xioctl(fd_, VIDIOC_S_FMT, &fmt) < 0) fail("VIDIOC_S_FMT");
    if (fmt.fmt.pix.pixelformat != V4L2_PIX_FMT_GREY || static_cast<int>(fmt.fmt.pix.width) != size.width ||
        static_cast<int>(fmt.fmt.pix.height) != size.height)
      throw std::runtime_error(device + ": the output gives " + std::to_string(fmt.fmt.pix.width) + "x" +
                               std::to_string(fmt.fmt.pix.height) + ", not GREY " +
                               std::to_string(size.width) + "x" + std::to_string(size.height) +
                               " (set its DV timings first)");
    stride_ = fmt.fmt.pix.bytesperline;
    v4l2_requestbuffers req{};
    req.count = 4;
    req.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    req.memory = V4L2_MEMORY_MMAP;
    if (xioctl(fd_, VIDIOC_REQBUFS, &req) < 0) fail("VIDIOC_REQBUFS");
    for (std::uint32_t i = 0; i < req.count; ++i) {
      v4l2_buffer buf{};
      buf.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
      buf.memory = V4L2_MEMORY_MMAP;
      buf.index = i;
      if (xioctl(fd_, VIDIOC_QUERYBUF, &buf) < 0) fail("VIDIOC_QUERYBUF");
      void* p = ::mmap(nullptr, buf.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, buf.m.offset);
      if (p == MAP_FAILED) fail("mmap");
      buffers_.push_back({static_cast<std::uint8_t*>(p), buf.length});
      free_.push_back(i);
    }
  }
  ~GreyOutput() {
    int type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    xioctl(fd_, VIDIOC_STREAMOFF, &type);
    for (auto& b : buffers_) ::munmap(b.data, b.length);
    ::close(fd_);
  }

  // Queues one frame; streaming starts with the second (vivid shows a buffer until the
  // next is queued, so it needs two).
  void write(const cv::Mat& grey) {
    const std::uint32_t i = take_buffer();
    for (int y = 0; y < size_.height; ++y)
      std::memcpy(buffers_[i].data + static_cast<std::size_t>(y) * stride_, grey.ptr(y),
                  static_cast<std::size_t>(size_.width));
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = i;
    buf.bytesused = stride_ * static_cast<std::uint32_t>(size_.height);
    buf.field = V4L2_FIELD_NONE;
    if (xioctl(fd_, VIDIOC_QBUF, &buf) < 0) fail("VIDIOC_QBUF");
    if (++queued_ == 2) {
      int type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
      if (xioctl(fd_, VIDIOC_STREAMON, &type) < 0) fail("VIDIOC_STREAMON");
    }
  }

 private:
  struct Buffer {
    std::uint8_t* data;
    std::size_t length;
  };
  [[noreturn]] void fail(const std::string& what) const {
    throw std::runtime_error(device_ + ": " + what + ": " + std::strerror(errno));
  }
  // A buffer not queued, else the next one the driver is done with (it lets one go
  // each output frame period while two or more are queued).
  std::uint32_t take_buffer() {
    if (!free_.empty()) {
      const std::uint32_t i = free_.back();
      free_.pop_back();
      return i;
    }
    for (;;) {
      pollfd p{fd_, POLLOUT, 0};
      const int r = ::poll(&p, 1, 1000);
      if (r < 0 && errno != EINTR) fail("poll");
      if (r == 0) throw std::runtime_error(device_ + ": no output buffer came back within 1 s");
      v4l2_buffer buf{};
      buf.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
      buf.memory = V4L2_MEMORY_MMAP;
      if (xioctl(fd_, VIDIOC_DQBUF, &buf) == 0) return buf.index;
      if (errno != EAGAIN) fail("VIDIOC_DQBUF");
    }
  }

  std::string device_;
  cv::Size size_;
  int fd_ = -1;
  std::uint32_t stride_ = 0;
  std::vector<Buffer> buffers_;
  std::vector<std::uint32_t> free_;
  int queued_ = 0;
};

int run(const std::string& dir, const std::string& left_dev, const std::string& right_dev) {
  const auto seq = dentmark::track::load_sequence(dir);
  const cv::Size size = seq.calibration.size;
  GreyOutput left(left_dev, size), right(right_dev, size);
  const auto& frames = seq.frames;
  // Every frame decoded before the clock starts: decoding a PNG takes a large share of
  // an emulated CPU, which the daemon needs while the door moves.
  const double t_load = now();
  std::vector<cv::Mat> left_frames, right_frames;
  for (const auto& f : frames) {
    left_frames.push_back(dentmark::track::load_grey(f.left, size));
    right_frames.push_back(dentmark::track::load_grey(f.right, size));
    if (g_stop) return 0;
  }
  std::printf("loaded %zu frames of %dx%d in %.1f s\n", frames.size(), size.width, size.height,
              now() - t_load);
  // Frame 0 twice: both outputs stream (and loop back) before the clock starts.
  for (int i = 0; i < 2; ++i) {
    left.write(left_frames[0]);
    right.write(right_frames[0]);
  }
  const double start = now() - frames[0].t;
  std::printf("streaming %zu frames (%.1f s) from %s to %s and %s\n", frames.size(),
              frames.back().t - frames[0].t, dir.c_str(), left_dev.c_str(), right_dev.c_str());
  std::fflush(stdout);
  double worst_late = 0.0;
  for (std::size_t k = 1; k < frames.size() && !g_stop; ++k) {
    const double due = start + frames[k].t;
    while (!g_stop && now() < due)
      std::this_thread::sleep_for(std::chrono::duration<double>(std::min(0.05, due - now())));
    worst_late = std::max(worst_late, now() - due);
    left.write(left_frames[k]);
    right.write(right_frames[k]);
  }
  std::printf("sequence done, the latest frame %.1f ms after its time; holding the last\n", 1e3 * worst_late);
  std::fflush(stdout);
  while (!g_stop) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: vivid_feeder SEQUENCE_DIR LEFT_OUTPUT_DEVICE RIGHT_OUTPUT_DEVICE\n");
    return 2;
  }
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);
  try {
    return run(argv[1], argv[2], argv[3]);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vivid_feeder: %s\n", e.what());
    return 1;
  }
}
