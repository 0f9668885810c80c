#include "dilate.h"

#include <algorithm>
#include <opencv2/imgproc.hpp>

#include "threads.h"

namespace dentmark::detect {

void dilate_in_strips(const cv::Mat& src, cv::Mat& dst, const cv::Mat& kernel) {
  // In place, the strips would read rows their neighbours already wrote.
  const cv::Mat in = src.data == dst.data ? src.clone() : src;
  dst.create(in.size(), in.type());
  // A strip of fewer rows than the kernel's height would cost more in margins than it saves.
  const int strips = std::clamp(in.rows / std::max(1, 2 * kernel.rows), 1, detail::thread_count());
  detail::for_each_part(static_cast<std::size_t>(strips), [&](std::size_t s) {
    const int r0 = static_cast<int>(in.rows * s / strips), r1 = static_cast<int>(in.rows * (s + 1) / strips);
    cv::Mat part = dst.rowRange(r0, r1);  // a view: dilate writes into dst
    cv::dilate(in.rowRange(r0, r1), part, kernel);
  });
}

}  // namespace dentmark::detect
