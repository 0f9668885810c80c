#pragma once
// Replays one side of a recorded or rendered sequence folder in the tracker's format
// (firmware/include/dentmark/firmware/track/sequence.h): frames.csv with the header
// `index,t,left,right` and image paths relative to the folder. Frames are released
// at their recorded pace on the injected clock (the first frame at start()), or as
// fast as they are read when 'paced' is false.

#include <filesystem>
#include <vector>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/hal/camera/camera.h"

namespace dentmark::hal {

enum class StereoSide { kLeft, kRight };

struct ReplayEntry {
  long index = 0;
  double t = 0.0;  // s, strictly increasing
  std::filesystem::path image;
};

// Reads frames.csv for one side. Throws CameraError "<file>:<line>: <problem>".
std::vector<ReplayEntry> read_replay_index(const std::filesystem::path& dir, StereoSide side);

class ReplayCamera final : public Camera {
 public:
  ReplayCamera(const std::filesystem::path& dir, StereoSide side, clock::Clock& clock, bool paced = true);
  void start() override;
  void stop() override { started_ = false; }
  std::optional<Frame> grab(double timeout) override;
  bool exhausted() const override { return next_ >= entries_.size(); }
  cv::Size size() const override { return size_; }
  const std::string& name() const override { return name_; }
  // Frame times are the recorded t shifted so that the first frame is at start() on
  // the clock; this returns the shift (clock time - recorded time).
  double time_offset() const { return offset_; }

 private:
  std::vector<ReplayEntry> entries_;
  clock::Clock& clock_;
  bool paced_;
  std::string name_;
  cv::Size size_;
  std::size_t next_ = 0;
  double offset_ = 0.0;
  bool started_ = false;
};

}  // namespace dentmark::hal
