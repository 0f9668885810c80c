#include "stereo_renderer.h"

#include <opencv2/imgproc.hpp>

namespace dentmark::calibrate::test {

Texture chessboard_texture(int cols, int rows, double square_m, int px_per_square) {
  // cols+1 × rows+1 squares plus one square of white margin on every side.
  const int w = (cols + 3) * px_per_square, h = (rows + 3) * px_per_square;
  Texture t;
  t.image = cv::Mat(h, w, CV_8UC1, cv::Scalar(215));
  for (int j = 0; j <= rows; ++j)
    for (int i = 0; i <= cols; ++i)
      if ((i + j) % 2 == 0)
        t.image(cv::Rect((i + 1) * px_per_square, (j + 1) * px_per_square, px_per_square, px_per_square))
            .setTo(cv::Scalar(40));
  // Pixel k covers [k − 0.5, k + 0.5]: the edge between squares 1 and 2 (the first
  // inner corner) is at 2·px_per_square − 0.5.
  const double scale = px_per_square / square_m, origin = 2.0 * px_per_square - 0.5;
  t.texture_from_board = cv::Matx33d(scale, 0, origin, 0, scale, origin, 0, 0, 1);
  return t;
}

cv::Mat render_view(const Texture& tex, const cv::Matx33d& K, const cv::Matx33d& R, const cv::Vec3d& t,
                    const RenderSettings& s, cv::RNG& rng) {
  // image ← board: K [r1 r2 t] (the board's plane z = 0).
  const cv::Matx33d image_from_board =
      K * cv::Matx33d(R(0, 0), R(0, 1), t[0], R(1, 0), R(1, 1), t[1], R(2, 0), R(2, 1), t[2]);
  // Supersampled image: pixel centre x maps to ss·x + (ss − 1)/2.
  const double ss = s.supersample;
  const cv::Matx33d hi_from_image(ss, 0, (ss - 1) / 2, 0, ss, (ss - 1) / 2, 0, 0, 1);
  const cv::Matx33d hi_from_texture = hi_from_image * image_from_board * tex.texture_from_board.inv();
  cv::Mat hi;
  cv::warpPerspective(tex.image, hi, cv::Mat(hi_from_texture),
                      cv::Size(s.size.width * s.supersample, s.size.height * s.supersample), cv::INTER_LINEAR,
                      cv::BORDER_CONSTANT, cv::Scalar(120));
  cv::Mat lo;
  cv::resize(hi, lo, s.size, 0, 0, cv::INTER_AREA);
  cv::Mat f;
  lo.convertTo(f, CV_32F);
  if (s.blur_sigma_px > 0) cv::GaussianBlur(f, f, cv::Size(0, 0), s.blur_sigma_px);
  cv::Mat noise(f.size(), CV_32F);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, s.noise_sigma);
  f += noise;
  cv::Mat out;
  f.convertTo(out, CV_8U);
  return out;
}

}  // namespace dentmark::calibrate::test
