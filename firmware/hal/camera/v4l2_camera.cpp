#include "dentmark/firmware/hal/camera/v4l2_camera.h"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>

#include "dentmark/common/log.h"

namespace dentmark::hal {
namespace {

int xioctl(int fd, unsigned long request, void* arg) {
  int r;
  do {
    r = ::ioctl(fd, request, arg);
  } while (r < 0 && errno == EINTR);
  return r;
}

double monotonic_now() {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// Formats we take, best first: grey needs no conversion; the others carry full-resolution luma.
constexpr std::uint32_t kFormats[] = {V4L2_PIX_FMT_GREY, V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_UYVY,
                                      V4L2_PIX_FMT_NV12, V4L2_PIX_FMT_NV21};

}  // namespace

std::string fourcc_name(std::uint32_t f) {
  std::string s(4, ' ');
  for (int i = 0; i < 4; ++i) s[static_cast<std::size_t>(i)] = static_cast<char>((f >> (8 * i)) & 0xFF);
  return s;
}

cv::Mat luma_from_buffer(const std::uint8_t* data, std::size_t bytesused, std::uint32_t fourcc, int width,
                         int height, std::uint32_t bytesperline) {
  if (width <= 0 || height <= 0) throw CameraError("frame size must be positive");
  int bpp = 0, offset = 0;  // bytes per pixel in the luma plane, offset of Y within a pixel
  int r = -1, b = -1;       // packed RGB: byte offsets of red and blue (green is 1)
  switch (fourcc) {
    case V4L2_PIX_FMT_GREY:
    case V4L2_PIX_FMT_NV12:
    case V4L2_PIX_FMT_NV21:
      bpp = 1;
      break;
    case V4L2_PIX_FMT_YUYV:
      bpp = 2;
      break;
    case V4L2_PIX_FMT_UYVY:
      bpp = 2;
      offset = 1;
      break;
    case V4L2_PIX_FMT_RGB24:
      bpp = 3, r = 0, b = 2;
      break;
    case V4L2_PIX_FMT_BGR24:
      bpp = 3, r = 2, b = 0;
      break;
    default:
      throw CameraError("pixel format " + fourcc_name(fourcc) + " is not supported");
  }
  const std::size_t min_stride = static_cast<std::size_t>(width) * bpp;
  const std::size_t stride = bytesperline ? bytesperline : min_stride;
  if (stride < min_stride)
    throw CameraError("bytesperline " + std::to_string(stride) + " is below the row size");
  const std::size_t need = stride * static_cast<std::size_t>(height - 1) + min_stride;
  if (bytesused < need)
    throw CameraError("frame buffer holds " + std::to_string(bytesused) + " bytes, the luma needs " +
                      std::to_string(need));
  cv::Mat out(height, width, CV_8UC1);
  for (int y = 0; y < height; ++y) {
    const std::uint8_t* row = data + stride * static_cast<std::size_t>(y);
    std::uint8_t* dst = out.ptr<std::uint8_t>(y);
    if (bpp == 1) {
      std::memcpy(dst, row, static_cast<std::size_t>(width));
    } else if (bpp == 3) {
      // ITU-R BT.601 luma, Y = 0.299 R + 0.587 G + 0.114 B, in 8-bit fixed point
      // (weights 77, 150, 29 of 256, rounded), as OpenCV's RGB->GRAY.
      for (int x = 0; x < width; ++x) {
        const std::uint8_t* p = row + 3 * x;
        dst[x] = static_cast<std::uint8_t>((77 * p[r] + 150 * p[1] + 29 * p[b] + 128) >> 8);
      }
    } else {
      for (int x = 0; x < width; ++x) dst[x] = row[2 * x + offset];
    }
  }
  return out;
}

V4l2Camera::V4l2Camera(std::string device, cv::Size size, unsigned buffers)
    : device_(std::move(device)), size_(size), want_buffers_(std::max(4u, buffers)) {}

V4l2Camera::~V4l2Camera() {
  stop();
}

void V4l2Camera::fail(const std::string& what, int err) const {
  throw CameraError(device_ + ": " + what + ": " + std::strerror(err));
}

void V4l2Camera::negotiate_format() {
  const v4l2_buf_type type = mplane_ ? V4L2_BUF_TYPE_VIDEO_CAPTURE_MPLANE : V4L2_BUF_TYPE_VIDEO_CAPTURE;
  std::string tried;
  for (std::uint32_t want : kFormats) {
    v4l2_format fmt{};
    fmt.type = type;
    if (mplane_) {
      fmt.fmt.pix_mp.width = static_cast<std::uint32_t>(size_.width);
      fmt.fmt.pix_mp.height = static_cast<std::uint32_t>(size_.height);
      fmt.fmt.pix_mp.pixelformat = want;
      fmt.fmt.pix_mp.field = V4L2_FIELD_NONE;
    } else {
      fmt.fmt.pix.width = static_cast<std::uint32_t>(size_.width);
      fmt.fmt.pix.height = static_cast<std::uint32_t>(size_.height);
      fmt.fmt.pix.pixelformat = want;
      fmt.fmt.pix.field = V4L2_FIELD_NONE;
    }
    if (xioctl(fd_, VIDIOC_S_FMT, &fmt) < 0) {
      if (errno == EBUSY) fail("VIDIOC_S_FMT", errno);
      continue;
    }
    // The driver may have changed anything: believe only what it reads back.
    v4l2_format got{};
    got.type = type;
    if (xioctl(fd_, VIDIOC_G_FMT, &got) < 0) fail("VIDIOC_G_FMT", errno);
    const std::uint32_t pf = mplane_ ? got.fmt.pix_mp.pixelformat : got.fmt.pix.pixelformat;
    const std::uint32_t w = mplane_ ? got.fmt.pix_mp.width : got.fmt.pix.width;
    const std::uint32_t h = mplane_ ? got.fmt.pix_mp.height : got.fmt.pix.height;
    tried +=
        (tried.empty() ? "" : ", ") + fourcc_name(pf) + " " + std::to_string(w) + "x" + std::to_string(h);
    if (pf != want) continue;
    if (w != static_cast<std::uint32_t>(size_.width) || h != static_cast<std::uint32_t>(size_.height))
      throw CameraError(device_ + ": asked " + std::to_string(size_.width) + "x" +
                        std::to_string(size_.height) + ", the driver gives " + std::to_string(w) + "x" +
                        std::to_string(h));
    fourcc_ = pf;
    bytesperline_ = mplane_ ? got.fmt.pix_mp.plane_fmt[0].bytesperline : got.fmt.pix.bytesperline;
    return;
  }
  throw CameraError(device_ + ": no usable pixel format (GREY, YUYV, UYVY, NV12, NV21); driver offered " +
                    (tried.empty() ? std::string("none") : tried));
}

void V4l2Camera::queue(std::uint32_t index) {
  v4l2_buffer buf{};
  v4l2_plane planes[VIDEO_MAX_PLANES]{};
  buf.type = mplane_ ? V4L2_BUF_TYPE_VIDEO_CAPTURE_MPLANE : V4L2_BUF_TYPE_VIDEO_CAPTURE;
  buf.memory = V4L2_MEMORY_MMAP;
  buf.index = index;
  if (mplane_) {
    buf.m.planes = planes;
    buf.length = 1;
  }
  if (xioctl(fd_, VIDIOC_QBUF, &buf) < 0) fail("VIDIOC_QBUF", errno);
}

void V4l2Camera::start() {
  if (fd_ >= 0) return;
  fd_ = ::open(device_.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) fail("open", errno);
  try {
    v4l2_capability cap{};
    if (xioctl(fd_, VIDIOC_QUERYCAP, &cap) < 0) fail("VIDIOC_QUERYCAP (not a V4L2 device?)", errno);
    const std::uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
    if (caps & V4L2_CAP_VIDEO_CAPTURE_MPLANE)
      mplane_ = true;
    else if (caps & V4L2_CAP_VIDEO_CAPTURE)
      mplane_ = false;
    else
      throw CameraError(device_ + ": not a video capture device");
    if (!(caps & V4L2_CAP_STREAMING)) throw CameraError(device_ + ": no streaming I/O");
    negotiate_format();

    v4l2_requestbuffers req{};
    req.count = want_buffers_;
    req.type = mplane_ ? V4L2_BUF_TYPE_VIDEO_CAPTURE_MPLANE : V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = V4L2_MEMORY_MMAP;
    if (xioctl(fd_, VIDIOC_REQBUFS, &req) < 0) fail("VIDIOC_REQBUFS", errno);
    if (req.count < 4)
      throw CameraError(device_ + ": driver granted " + std::to_string(req.count) +
                        " buffers, need at least 4");
    buffers_.resize(req.count);
    for (std::uint32_t i = 0; i < req.count; ++i) {
      v4l2_buffer buf{};
      v4l2_plane planes[VIDEO_MAX_PLANES]{};
      buf.type = req.type;
      buf.memory = V4L2_MEMORY_MMAP;
      buf.index = i;
      if (mplane_) {
        buf.m.planes = planes;
        buf.length = VIDEO_MAX_PLANES;
      }
      if (xioctl(fd_, VIDIOC_QUERYBUF, &buf) < 0) fail("VIDIOC_QUERYBUF", errno);
      // Multi-planar: the luma is plane 0 for every format we accept.
      const std::size_t length = mplane_ ? planes[0].length : buf.length;
      const off_t offset = mplane_ ? planes[0].m.mem_offset : buf.m.offset;
      void* p = ::mmap(nullptr, length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, offset);
      if (p == MAP_FAILED) fail("mmap", errno);
      buffers_[i] = {p, length};
    }
    for (std::uint32_t i = 0; i < req.count; ++i) queue(i);
    int type = static_cast<int>(req.type);
    if (xioctl(fd_, VIDIOC_STREAMON, &type) < 0) fail("VIDIOC_STREAMON", errno);
    streaming_ = true;
  } catch (...) {
    stop();
    throw;
  }
}

void V4l2Camera::stop() {
  if (fd_ < 0) return;
  const v4l2_buf_type type = mplane_ ? V4L2_BUF_TYPE_VIDEO_CAPTURE_MPLANE : V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (streaming_) {
    int t = static_cast<int>(type);
    xioctl(fd_, VIDIOC_STREAMOFF, &t);  // also dequeues every buffer
    streaming_ = false;
  }
  if (corrupted_ > 0)
    log::warn(device_ + ": " + std::to_string(corrupted_) +
              " frames flagged corrupted by the driver were dropped");
  for (auto& b : buffers_)
    if (b.start) ::munmap(b.start, b.length);
  if (!buffers_.empty()) {
    v4l2_requestbuffers req{};
    req.count = 0;  // frees the driver's buffers
    req.type = type;
    req.memory = V4L2_MEMORY_MMAP;
    xioctl(fd_, VIDIOC_REQBUFS, &req);
  }
  buffers_.clear();
  ::close(fd_);
  fd_ = -1;
}

std::optional<Frame> V4l2Camera::grab(double timeout) {
  if (!streaming_) throw CameraError(device_ + ": grab before start");
  using clock = std::chrono::steady_clock;
  const auto end = clock::now() + std::chrono::duration<double>(std::max(0.0, timeout));
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(end - clock::now()).count();
    pollfd p{fd_, POLLIN, 0};
    const int r = ::poll(&p, 1, static_cast<int>(std::max<long long>(0, left)));
    if (r < 0) {
      if (errno == EINTR) continue;  // a signal: the deadline still holds
      fail("poll", errno);
    }
    if (r == 0) return std::nullopt;
    if (p.revents & POLLERR)
      throw CameraError(device_ + ": poll reports an error (device gone or stream stopped)");
    v4l2_buffer buf{};
    v4l2_plane planes[VIDEO_MAX_PLANES]{};
    buf.type = mplane_ ? V4L2_BUF_TYPE_VIDEO_CAPTURE_MPLANE : V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    if (mplane_) {
      buf.m.planes = planes;
      buf.length = VIDEO_MAX_PLANES;
    }
    if (xioctl(fd_, VIDIOC_DQBUF, &buf) < 0) {
      if (errno == EAGAIN) continue;  // woken without a ready buffer
      fail("VIDIOC_DQBUF", errno);
    }
    if (buf.index >= buffers_.size())
      throw CameraError(device_ + ": driver returned buffer index out of range");
    if (buf.flags & V4L2_BUF_FLAG_ERROR) {  // corrupted frame: hand the buffer back, wait for the next
      ++corrupted_;
      queue(buf.index);
      continue;
    }
    Frame f;
    const std::size_t used = mplane_ ? planes[0].bytesused - planes[0].data_offset : buf.bytesused;
    const auto* data =
        static_cast<const std::uint8_t*>(buffers_[buf.index].start) + (mplane_ ? planes[0].data_offset : 0);
    try {
      f.image = luma_from_buffer(data, used, fourcc_, size_.width, size_.height, bytesperline_);
    } catch (...) {
      queue(buf.index);
      throw;
    }
    queue(buf.index);  // the frame owns a copy: the buffer goes straight back to the driver
    const bool monotonic = (buf.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
    f.time = monotonic ? static_cast<double>(buf.timestamp.tv_sec) +
                             1e-6 * static_cast<double>(buf.timestamp.tv_usec)
                       : monotonic_now();
    f.sequence = buf.sequence;
    return f;
  }
}

}  // namespace dentmark::hal
