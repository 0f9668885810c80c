#pragma once
// The optics and sensor after the ray tracer's irradiance image: defocus (a uniform
// disc, the thin lens's circle of confusion), natural vignetting (cos^4 of the ray's
// angle), a Bayer RGGB colour filter, photon (Poisson) noise on the electrons, read
// noise, a 10-bit ADC with black level, OpenCV's bilinear demosaicing, white balance
// and a display gamma: an 8-bit BGR image as a colour camera delivers it.

#include <opencv2/core.hpp>
#include <random>

namespace dentmark::sim::raytrace {

struct SensorOptions {
  double electrons_at_white = 14000.0;           // reflectance 1 under light level 1
  double full_well = 16000.0;                    // electrons; the ADC's full scale
  cv::Vec3d channel_response{0.58, 0.80, 0.62};  // R, G, B filter × quantum efficiency
  double read_noise = 4.0;                       // electrons RMS
  int black_level = 32;                          // DN of 1023
  double gamma = 2.2;
  double defocus_radius = 0.7;  // px: radius of the circle of confusion (0: in focus)
  bool bayer = true;            // false: a monochrome sensor (no mosaic)
};

// Radius in pixels of the thin lens's circle of confusion for a plane at `depth` when
// focused at `focus` (metres), with f-number N, focal length f (m) and pixel pitch (m).
double circle_of_confusion_px(double depth, double focus, double f_number, double focal_m, double pitch_m);

// corner_rays: the ray tracer's (H + 1) x (W + 1) undistorted normalised pixel corners.
cv::Mat3b expose(const cv::Mat3f& irradiance, const cv::Mat2d& corner_rays, const SensorOptions& o,
                 std::mt19937_64& rng);

}  // namespace dentmark::sim::raytrace
