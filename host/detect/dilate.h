#pragma once
// Dilation of a mask on horizontal strips side by side: OpenCV's morphology runs on one
// thread (ocvMorph applies one filter over the whole image).

#include <opencv2/core.hpp>

namespace dentmark::detect {

// cv::dilate(src, dst, kernel) with its default anchor and border: the same pixels, since
// each strip is dilated as a view of the whole image and so reads the rows around it.
// dst keeps its buffer when it has src's size and type; it may be src itself.
void dilate_in_strips(const cv::Mat& src, cv::Mat& dst, const cv::Mat& kernel);

}  // namespace dentmark::detect
