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
  int levels = 2;   // pyramid levels above the image (the prediction brings LK close)
  int iterations = 30;
  double epsilon = 0.01;
};

// The pyramid of one image, built once, optionally only over a region (where the
// features can be this frame): the levels then cover that region, whose origin is a
// multiple of 2^levels so every level halves the one below exactly.
class ImagePyramid {
 public:
  ImagePyramid() = default;
  ImagePyramid(const cv::Mat& grey, const LkOptions& options, cv::Rect region = {});
  bool empty() const { return levels_.empty(); }
  cv::Size size() const { return image_.size(); }  // of the whole image
  const cv::Mat& image() const { return image_; }  // the whole image (shared, not copied)
  const std::vector<cv::Mat>& levels() const { return levels_; }
  cv::Rect region() const { return region_; }  // what the levels cover, level-0 pixels

 private:
  cv::Mat image_;
  std::vector<cv::Mat> levels_;
  cv::Rect region_;
};

// Tracks from → to: p_from in `from`, starting guess in `to`. Nothing when LK fails or
// the point leaves the image.
std::optional<cv::Point2f> track_lk(const ImagePyramid& from, const ImagePyramid& to,
                                    const cv::Point2f& p_from, const cv::Point2f& guess,
                                    const LkOptions& options);

}  // namespace dentmark::track
