#pragma once
// A second, independent stereo renderer of the moving door for the tracker's tests
// (docs/tracking.md, "Two renderers"). It shares no code with sim/stereo: per-pixel ray
// tracing with supersampled edges (ray_tracer.h) through Brown-Conrady lenses (lens.h),
// motion blur over the exposure, defocus, vignetting, a lighting gradient fixed in the
// station that drifts over time, Poisson and read noise on a Bayer sensor with
// demosaicing and gamma (sensor.h). It writes the tracker's replay format (through
// common/replay_files.h and common/stereo_index.h, as sim/stereo does):
//   stereo.yaml  (image_width, image_height, K1, D1, K2, D2, R, T; the exact lenses)
//   frames.csv   (index,t,left,right; 8-bit BGR PNGs; t is the middle of the exposure)
//   seeds.yaml   (seeds_right: rough right-image corners of frame 0)
//   truth.csv    (index,t,m00..m23: the true M(k) at mid-exposure)
//   eval_points.csv (x,y,z: points on the lower door, camL at frame 0)
//   features.csv (x,y,z: the window frame corners, camL at frame 0)

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>

#include "dentmark/sim/stereo_raytrace/sensor.h"

namespace dentmark::sim::raytrace {

struct RaySequenceOptions {
  int width = 1280;
  int height = 1024;
  double focal_px = 1740.0;
  double pixel_pitch = 5.3e-6;  // m at this resolution (binned sensors: larger)
  double baseline = 0.5;        // m
  double distance = 2.8;        // m, camL to the door
  double seconds = 3.9;         // 40 frames at 10 fps
  double fps = 10.0;
  double speed = 0.014;     // m/s
  double exposure = 0.008;  // s; motion blur over it
  int exposure_steps = 8;   // poses across the exposure
  int supersample = 6;      // n x n sub-rays in edge pixels
  bool distortion = true;   // Brown-Conrady lenses (false: ideal pinholes)
  double f_number = 1.4;
  double focus = 2.3;            // m: the door at `distance` is slightly out of focus
  double lighting_drift = 0.15;  // relative swing of the light level over the run
  bool occlude = false;          // the arm hides the frame's left end from 30 % to 60 % of the run
  double stop_at = -1.0;         // s the line starts to stop (< 0: never)
  double stop_for = 0.0;         // s at rest
  double turn_rate = 0.0;        // rad/s: the panel turns about camL y (not a plain conveyor)
  double seed_error = 3.0;       // px, uniform in [-e, e] per axis
  SensorOptions sensor;
  std::uint64_t seed = 7;
};

class RaySequenceError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A one-line description of every option (a cache key for rendered sequences).
std::string describe(const RaySequenceOptions& o);

// Renders into a sibling of dir and renames it to dir (dir must not exist or be empty).
// Throws RaySequenceError on bad options or I/O failure.
void write_ray_sequence(const RaySequenceOptions& options, const std::filesystem::path& dir);

}  // namespace dentmark::sim::raytrace
