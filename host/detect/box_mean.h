#pragma once
// The weighted mean of a deviation image over k x k windows, where enough of the window
// is seen: what the detector's deviation test thresholds at each scale.

#include <opencv2/core.hpp>

namespace dentmark::detect {

// out(r, c) = Σ values / Σ weights over the k x k window centred at (r, c) (k odd,
// nothing outside the image), or NaN where Σ weights < min_weight. values holds each
// pixel's weight times its value (0 where unseen); all three images are CV_32F of the
// same size; out is (re)allocated.
void box_mean(const cv::Mat& values, const cv::Mat& weights, int k, float min_weight, cv::Mat& out);

}  // namespace dentmark::detect
