#include "dentmark/firmware/hal/camera/replay_camera.h"

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "dentmark/common/image/png_io.h"
#include "dentmark/common/stereo_index.h"

namespace dentmark::hal {
namespace {

cv::Mat read_grey(const std::filesystem::path& path) {
  cv::Mat img;
  try {
    img = image::read_png(path.string());
  } catch (const image::ImageError& e) {
    throw CameraError(e.what());
  }
  if (img.depth() != CV_8U) throw CameraError(path.string() + ": expected an 8-bit image");
  if (img.channels() == 3) cv::cvtColor(img, img, cv::COLOR_BGR2GRAY);
  return img;
}

}  // namespace

std::vector<ReplayEntry> read_replay_index(const std::filesystem::path& dir, StereoSide side) {
  std::vector<ReplayEntry> out;
  try {
    for (const files::StereoIndexEntry& e : files::read_stereo_index(dir))
      out.push_back({e.index, e.t, side == StereoSide::kLeft ? e.left : e.right});
  } catch (const files::StereoIndexError& e) {
    throw CameraError(e.what());
  }
  return out;
}

ReplayCamera::ReplayCamera(const std::filesystem::path& dir, StereoSide side, clock::Clock& clock, bool paced)
    : entries_(read_replay_index(dir, side)),
      clock_(clock),
      paced_(paced),
      name_("replay:" + dir.string() + (side == StereoSide::kLeft ? ":left" : ":right")) {
  size_ = read_grey(entries_.front().image).size();
}

void ReplayCamera::start() {
  next_ = 0;
  offset_ = clock_.now() - entries_.front().t;
  started_ = true;
}

std::optional<Frame> ReplayCamera::grab(double timeout) {
  if (!started_) throw CameraError(name_ + ": grab before start");
  if (exhausted()) return std::nullopt;
  const ReplayEntry& e = entries_[next_];
  const double due = e.t + offset_;
  if (paced_) {
    const double wait = due - clock_.now();
    if (clock_.to_real(wait) > timeout) {
      clock_.sleep_for(timeout <= 0 ? 0.0 : timeout / clock_.to_real(1.0));
      return std::nullopt;
    }
    clock_.sleep_until(due);
  }
  Frame f;
  f.image = read_grey(e.image);
  if (f.image.size() != size_)
    throw CameraError(e.image.string() + ": image is " + std::to_string(f.image.cols) + "x" +
                      std::to_string(f.image.rows) + ", the sequence's first is " +
                      std::to_string(size_.width) + "x" + std::to_string(size_.height));
  f.time = due;
  f.sequence = static_cast<std::uint64_t>(e.index);
  ++next_;
  return f;
}

}  // namespace dentmark::hal
