#include "dentmark/firmware/hal/camera/sim_camera.h"

#include <cmath>

namespace dentmark::hal {

SimCamera::SimCamera(std::string name, cv::Size size, double period, Render render, clock::Clock& clock,
                     double offset, std::uint64_t frames)
    : name_(std::move(name)),
      size_(size),
      period_(period),
      render_(std::move(render)),
      clock_(clock),
      offset_(offset),
      frames_(frames) {
  if (!(period > 0.0) || !std::isfinite(period)) throw CameraError(name_ + ": frame period must be > 0");
  if (!render_) throw CameraError(name_ + ": no renderer");
}

void SimCamera::start() {
  // Frames fall on a grid offset + k * period shared by every camera with the same
  // period (one time base, like sensors on a common trigger clock), starting at the
  // first grid point from now.
  // A grid point less than a microsecond past counts as now (a clock started a moment
  // ago must still take the frame at its start).
  first_ = static_cast<std::uint64_t>(std::max(0.0, std::ceil((clock_.now() - offset_) / period_ - 1e-6)));
  next_ = first_;
  started_ = true;
}

std::optional<Frame> SimCamera::grab(double timeout) {
  if (!started_) throw CameraError(name_ + ": grab before start");
  if (exhausted()) return std::nullopt;
  const double due = offset_ + static_cast<double>(next_) * period_;
  const double wait = due - clock_.now();
  if (wait > 0.0 && clock_.to_real(wait) > timeout) {
    if (timeout > 0.0) clock_.sleep_for(timeout / clock_.to_real(1.0));
    return std::nullopt;
  }
  clock_.sleep_until(due);
  Frame f;
  f.image = render_(due);
  if (f.image.size() != size_ || f.image.type() != CV_8UC1)
    throw CameraError(name_ + ": renderer returned an image of the wrong size or type");
  f.time = due;
  f.sequence = next_++;
  return f;
}

}  // namespace dentmark::hal
