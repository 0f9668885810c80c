#pragma once
// Pyramidal Lucas-Kanade on pyramids built once per image. Each feature is tracked on
// a window of the shared pyramid levels (views, no copies), so the cost per frame is a
// few small windows, not whole-image derivatives.

#include <opencv2/core.hpp>
#include <optional>
#include <vector>

namespace dentmark::track {

struct LkOptions {
  int window = 21;  // LK integration window, px
  int levels = 3;   // pyramid levels above the image
  int iterations = 30;
  double epsilon = 0.01;
};

class ImagePyramid {
 public:
  ImagePyramid() = default;
  ImagePyramid(const cv::Mat& grey, const LkOptions& options);
  bool empty() const { return levels_.empty(); }
  cv::Size size() const { return levels_.empty() ? cv::Size() : levels_[0].size(); }
  const cv::Mat& image() const { return levels_[0]; }
  const std::vector<cv::Mat>& levels() const { return levels_; }

 private:
  std::vector<cv::Mat> levels_;
};

// Tracks from → to: p_from in `from`, starting guess in `to`. Nothing when LK fails or
// the point leaves the image.
std::optional<cv::Point2f> track_lk(const ImagePyramid& from, const ImagePyramid& to,
                                    const cv::Point2f& p_from, const cv::Point2f& guess,
                                    const LkOptions& options);

}  // namespace dentmark::track
