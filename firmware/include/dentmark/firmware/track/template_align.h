#pragma once
// Sub-pixel refinement of a feature against its reference template: Gauss-Newton
// (Lucas-Kanade, forward additive) over translation plus a gain and an offset, so the
// ±30 % lighting drift of a line does not bias the position. Matching the first
// frame's template, not the previous frame's, keeps every frame on the same physical
// point: no drift, and no corner-detector bias that changes with the sub-pixel phase.

#include <opencv2/core.hpp>
#include <optional>

namespace dentmark::track {

struct AlignOptions {
  int iterations = 15;
  double epsilon = 1e-3;   // px: stop when the step is smaller
  double max_shift = 2.0;  // px from the start
};

struct Alignment {
  cv::Point2f position;
  double ncc = 0.0;  // of the aligned patch with the template
};

// A template cut on the pixel grid (no interpolation) around the pixel nearest p, and
// p's offset from that pixel: the feature sits at (aligned template centre + offset).
struct GridTemplate {
  cv::Mat patch;  // CV_32F, empty when it would leave the image
  cv::Point2f offset;
};
GridTemplate grid_template(const cv::Mat& grey, const cv::Point2f& p, int half);

// The (2 half + 1)^2 patch whose pixel u (offset from the centre) is grey at
// centre + A u, bicubic: a patch seen through a local affine map, e.g. the other
// camera's view of the same plane (CV_32F; empty when it would leave the image).
cv::Mat affine_patch(const cv::Mat& grey, const cv::Point2d& centre, const cv::Matx22d& A, int half);

// templ: CV_32F, odd square size. Nothing when the patch leaves the image, the
// solution diverges or moves further than max_shift.
std::optional<Alignment> align_template(const cv::Mat& grey, const cv::Mat& templ, const cv::Point2f& start,
                                        const AlignOptions& options = {});

}  // namespace dentmark::track
