#pragma once
// A camera through libcamera (Debian 12: 0.0.3), for CSI sensors behind an ISP
// (Raspberry Pi 5, design.md §5). The stream is configured for the board's size in
// a format whose luma we can read (R8, YUYV, UYVY, NV12, NV21), read back after
// validate(); at least 4 buffers are allocated, mapped once and cycled through
// requests. Completed requests are handed over from libcamera's thread through a
// queue, never processed on it.
// Built only where libcamera is found (DENTMARK_HAVE_LIBCAMERA).

#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <vector>

#include "dentmark/firmware/hal/camera/camera.h"

namespace libcamera {
class Camera;
class CameraManager;
class FrameBufferAllocator;
class Request;
class Stream;
}  // namespace libcamera

namespace dentmark::hal {

// Ids of the cameras libcamera sees (empty where there are none).
std::vector<std::string> list_libcamera_cameras();

class LibcameraCamera final : public Camera {
 public:
  // id: libcamera camera id (board file camera.left/right); empty = the first camera.
  LibcameraCamera(std::string id, cv::Size size, unsigned buffers = 4);
  ~LibcameraCamera() override;
  LibcameraCamera(const LibcameraCamera&) = delete;
  LibcameraCamera& operator=(const LibcameraCamera&) = delete;

  void start() override;
  void stop() override;
  std::optional<Frame> grab(double timeout) override;
  cv::Size size() const override { return size_; }
  const std::string& name() const override { return id_; }

 private:
  void on_request_completed(libcamera::Request* request);
  struct Mapping {
    void* base = nullptr;
    std::size_t length = 0;
    std::size_t offset = 0;  // plane 0 start within the mapping
  };

  std::string id_;
  cv::Size size_;
  unsigned want_buffers_;
  std::unique_ptr<libcamera::CameraManager> manager_;
  std::shared_ptr<libcamera::Camera> camera_;
  std::unique_ptr<libcamera::FrameBufferAllocator> allocator_;
  libcamera::Stream* stream_ = nullptr;
  std::vector<std::unique_ptr<libcamera::Request>> requests_;
  std::vector<Mapping> mappings_;  // by request cookie
  std::uint32_t fourcc_ = 0;       // V4L2 fourcc of the luma layout
  std::uint32_t stride_ = 0;
  bool running_ = false;
  bool acquired_ = false;

  std::mutex mutex_;
  std::condition_variable completed_cv_;
  std::deque<libcamera::Request*> completed_;
};

}  // namespace dentmark::hal
