#include "dentmark/firmware/hal/camera/replay_camera.h"

#include <cmath>
#include <fstream>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "dentmark/common/image/png_io.h"

namespace dentmark::hal {
namespace {

std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  std::string cell;
  while (std::getline(ss, cell, ',')) {
    while (!cell.empty() && (cell.back() == '\r' || cell.back() == ' ')) cell.pop_back();
    while (!cell.empty() && cell.front() == ' ') cell.erase(cell.begin());
    out.push_back(cell);
  }
  return out;
}

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
  const auto csv = dir / "frames.csv";
  std::ifstream in(csv);
  if (!in) throw CameraError(csv.string() + ":0: cannot open for reading");
  std::string text;
  int line = 0;
  const auto fail = [&](const std::string& problem) {
    throw CameraError(csv.string() + ":" + std::to_string(line) + ": " + problem);
  };
  if (!std::getline(in, text)) fail("empty file");
  ++line;
  if (split_csv(text) != std::vector<std::string>{"index", "t", "left", "right"})
    fail("header must be 'index,t,left,right'");
  std::vector<ReplayEntry> out;
  while (std::getline(in, text)) {
    ++line;
    if (text.empty() || text == "\r") continue;
    const auto cells = split_csv(text);
    if (cells.size() != 4) fail("expected 4 fields, got " + std::to_string(cells.size()));
    ReplayEntry e;
    try {
      std::size_t used = 0;
      e.index = std::stol(cells[0], &used);
      if (used != cells[0].size()) throw std::invalid_argument("trailing");
      e.t = std::stod(cells[1], &used);
      if (used != cells[1].size()) throw std::invalid_argument("trailing");
    } catch (const std::exception&) {
      fail("index and t must be numbers");
    }
    if (!std::isfinite(e.t)) fail("t is not finite");
    if (!out.empty() && !(e.t > out.back().t)) fail("t must increase strictly");
    const std::string& rel = side == StereoSide::kLeft ? cells[2] : cells[3];
    if (rel.empty()) fail(std::string(side == StereoSide::kLeft ? "left" : "right") + " image path is empty");
    e.image = dir / rel;
    out.push_back(e);
  }
  if (out.empty()) fail("no frames");
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
