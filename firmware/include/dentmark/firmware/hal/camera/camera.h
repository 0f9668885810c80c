#pragma once
// A camera as the tracker sees it (design.md §5): start, grab the next frame with a
// timeout, stop. Frames carry the capture time on the monotonic line (kernel
// timestamps for V4L2 and libcamera; the injected clock for replay and simulation).
// Backends side by side: v4l2_camera.h, libcamera_camera.h, replay_camera.h,
// sim_camera.h.

#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <stdexcept>
#include <string>

namespace dentmark::hal {

class CameraError : public std::runtime_error {
 public:
  explicit CameraError(const std::string& what) : std::runtime_error(what) {}
};

struct Frame {
  cv::Mat image;               // 8-bit grey, owned by the frame (never a view into a driver buffer)
  double time = 0.0;           // s, capture time
  std::uint64_t sequence = 0;  // the source's frame counter (gaps mean dropped frames)
};

class Camera {
 public:
  virtual ~Camera() = default;
  virtual void start() = 0;
  virtual void stop() = 0;  // idempotent
  // The next frame, waiting at most 'timeout' real seconds; std::nullopt on timeout
  // or when a finite source is exhausted (see exhausted()). Throws CameraError on
  // device errors.
  virtual std::optional<Frame> grab(double timeout) = 0;
  virtual bool exhausted() const { return false; }
  virtual cv::Size size() const = 0;
  virtual const std::string& name() const = 0;
};

}  // namespace dentmark::hal
