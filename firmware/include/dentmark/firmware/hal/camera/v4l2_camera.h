#pragma once
// V4L2 capture with mmap streaming: single- and multi-planar API (whichever the
// device offers), pixel format negotiated and read back (GREY, Y16 is not used;
// YUYV/UYVY and NV12/NV21 give their luma), at least 4 buffers, poll + DQBUF with
// EINTR/EAGAIN handled, clean STREAMOFF and unmap. Kernel-level tests (vivid) belong
// to the QEMU system-test tier; the pixel conversion is tested everywhere.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "dentmark/firmware/hal/camera/camera.h"

namespace dentmark::hal {

// Luma of one frame as 8-bit grey. 'bytesperline' is the stride of the (first) plane.
// Throws CameraError when the buffer is too short or the format is not supported.
cv::Mat luma_from_buffer(const std::uint8_t* data, std::size_t bytesused, std::uint32_t fourcc, int width,
                         int height, std::uint32_t bytesperline);
// "YUYV" etc.
std::string fourcc_name(std::uint32_t fourcc);

class V4l2Camera final : public Camera {
 public:
  V4l2Camera(std::string device, cv::Size size, unsigned buffers = 4);
  ~V4l2Camera() override;
  V4l2Camera(const V4l2Camera&) = delete;
  V4l2Camera& operator=(const V4l2Camera&) = delete;

  void start() override;
  void stop() override;
  std::optional<Frame> grab(double timeout) override;
  cv::Size size() const override { return size_; }
  const std::string& name() const override { return device_; }
  bool multiplanar() const { return mplane_; }
  std::uint32_t fourcc() const { return fourcc_; }

 private:
  struct Buffer {
    void* start = nullptr;
    std::size_t length = 0;
  };
  void fail(const std::string& what, int err) const;
  void negotiate_format();
  void queue(std::uint32_t index);

  std::string device_;
  cv::Size size_;
  unsigned want_buffers_;
  int fd_ = -1;
  bool mplane_ = false;
  bool streaming_ = false;
  std::uint32_t fourcc_ = 0;
  std::uint32_t bytesperline_ = 0;
  std::vector<Buffer> buffers_;
  long corrupted_ = 0;
};

}  // namespace dentmark::hal
