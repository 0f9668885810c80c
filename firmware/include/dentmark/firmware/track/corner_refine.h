#pragma once
// Step A of paper §IV-A: a rough seed becomes a sub-pixel corner. The strongest
// Shi-Tomasi corner (minimum eigenvalue of the structure tensor) in a small window
// around the seed, favouring corners near it, then cv::cornerSubPix.

#include <opencv2/core.hpp>
#include <optional>

namespace dentmark::track {

struct CornerOptions {
  int search_radius = 10;  // px around the seed
  int subpix_half_window = 5;
};

// The refined corner, or nothing when the window holds no distinct corner or lies
// outside the image.
std::optional<cv::Point2f> refine_seed(const cv::Mat& grey, const cv::Point2f& seed,
                                       const CornerOptions& options);

// cv::cornerSubPix on one point; nothing when it leaves the image or moves further
// than max_shift px from the start.
std::optional<cv::Point2f> subpixel_corner(const cv::Mat& grey, const cv::Point2f& start, int half_window,
                                           double max_shift);

// Normalised cross-correlation of a template with the image patch of the same size
// centred at p (bilinear sampling). -1 when the patch leaves the image.
double patch_ncc(const cv::Mat& grey, const cv::Point2f& p, const cv::Mat& templ32f);

// The patch of size (2 half + 1)^2 centred at p, CV_32F.
cv::Mat patch_at(const cv::Mat& grey, const cv::Point2f& p, int half);

}  // namespace dentmark::track
