#include "dentmark/sim/stereo_raytrace/sensor.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace dentmark::sim::raytrace {
namespace {

// A uniform disc of radius r px, each kernel cell weighted by its covered area.
cv::Mat1f disc_kernel(double r) {
  const int half = static_cast<int>(std::ceil(r + 0.5));
  cv::Mat1f k(2 * half + 1, 2 * half + 1, 0.0f);
  constexpr int kSub = 16;
  for (int y = -half; y <= half; ++y)
    for (int x = -half; x <= half; ++x) {
      int in = 0;
      for (int j = 0; j < kSub; ++j)
        for (int i = 0; i < kSub; ++i) {
          const double px = x - 0.5 + (i + 0.5) / kSub, py = y - 0.5 + (j + 0.5) / kSub;
          in += px * px + py * py <= r * r;
        }
      k(y + half, x + half) = static_cast<float>(in);
    }
  return k / cv::sum(k)[0];
}

double electrons_with_noise(double mean, double read_noise, std::mt19937_64& rng) {
  double e;
  if (mean < 50.0) {
    e = std::poisson_distribution<int>(std::max(mean, 0.0))(rng);
  } else {  // Poisson's normal limit (exact to well under a DN here)
    e = mean + std::sqrt(mean) * std::normal_distribution<double>(0.0, 1.0)(rng);
  }
  return e + read_noise * std::normal_distribution<double>(0.0, 1.0)(rng);
}

}  // namespace

double circle_of_confusion_px(double depth, double focus, double f_number, double focal_m, double pitch_m) {
  const double aperture = focal_m / f_number;
  const double diameter = aperture * std::abs(depth - focus) / depth * focal_m / (focus - focal_m);
  return 0.5 * diameter / pitch_m;
}

cv::Mat3b expose(const cv::Mat3f& irradiance, const cv::Mat2d& corner_rays, const SensorOptions& o,
                 std::mt19937_64& rng) {
  const int w = irradiance.cols, h = irradiance.rows;
  cv::Mat3f img = irradiance.clone();
  if (o.defocus_radius > 0.3)
    cv::filter2D(img, img, -1, disc_kernel(o.defocus_radius), {-1, -1}, 0.0, cv::BORDER_REPLICATE);
  const double scale = 1023.0 - o.black_level;
  cv::Mat1w raw(h, w);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      // The pixel centre's ray: the mean of its corners.
      const cv::Vec2d c = 0.25 * (corner_rays(v, u) + corner_rays(v, u + 1) + corner_rays(v + 1, u) +
                                  corner_rays(v + 1, u + 1));
      const double cos2 = 1.0 / (1.0 + c[0] * c[0] + c[1] * c[1]);
      const cv::Vec3f& e = img(v, u);  // R, G, B (the ray tracer's order)
      // RGGB: R at even row/even column, B at odd/odd, G elsewhere.
      const int ch = o.bayer ? ((v % 2 == 0 && u % 2 == 0) ? 0 : (v % 2 == 1 && u % 2 == 1) ? 2 : 1) : 1;
      const double mean = o.electrons_at_white * o.channel_response[ch] * e[ch] * cos2 * cos2;
      const double electrons = electrons_with_noise(mean, o.read_noise, rng);
      const double dn = std::round(o.black_level + electrons / o.full_well * scale);
      raw(v, u) = static_cast<ushort>(std::clamp(dn, 0.0, 1023.0));
    }
  cv::Mat1w linear;
  cv::subtract(raw, cv::Scalar(o.black_level), linear);  // saturates at 0
  cv::Mat3f colour;
  if (o.bayer) {
    cv::Mat3w bgr;
    cv::cvtColor(linear, bgr, cv::COLOR_BayerBG2BGR);  // OpenCV's name for an RGGB mosaic
    bgr.convertTo(colour, CV_32F);
  } else {
    cv::Mat1f g;
    linear.convertTo(g, CV_32F);
    cv::cvtColor(g, colour, cv::COLOR_GRAY2BGR);
  }
  // White balance (the filters' response) and gamma to 8 bits.
  const double full = scale;
  const cv::Vec3d wb = o.bayer ? cv::Vec3d(o.channel_response[1] / o.channel_response[2], 1.0,
                                           o.channel_response[1] / o.channel_response[0])
                               : cv::Vec3d(1, 1, 1);  // B, G, R
  cv::Mat3b out(h, w);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u)
      for (int c = 0; c < 3; ++c) {
        const double x = std::clamp(colour(v, u)[c] * wb[c] / full, 0.0, 1.0);
        out(v, u)[c] = cv::saturate_cast<uchar>(255.0 * std::pow(x, 1.0 / o.gamma));
      }
  return out;
}

}  // namespace dentmark::sim::raytrace
