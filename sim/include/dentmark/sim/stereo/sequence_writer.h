#pragma once
// Writes a rendered stereo sequence in the tracker's replay format plus ground truth
// (written through common/replay_files.h and common/stereo_index.h):
//   stereo.yaml  (image_width, image_height, K1, D1, K2, D2, R, T; p_camR = R p_camL + T)
//   frames.csv   (index,t,left,right; PNG paths relative to the directory)
//   seeds.yaml   (seeds_right: N x 2 float, rough right-image corners of frame 0)
//   truth.csv    (index,t,m00..m23: the true M(k), camL at frame 0 to camL at frame k)
//   eval_points.csv (x,y,z: points on the lower door panel, camL at frame 0, metres)
//   features.csv (x,y,z: the macro-features, camL at frame 0, metres)

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>

namespace dentmark::sim::stereo {

struct SequenceOptions {
  int width = 1280;
  int height = 1024;
  double focal_px = 1740.0;
  double baseline = 0.5;  // m
  double distance = 2.8;  // m, camL to the door
  double seconds = 40.0;
  double fps = 10.0;
  double speed = 0.014;      // m/s
  double vibration = 1e-4;   // m
  double lighting = 0.3;     // relative gain swing (0.3: ±30 %)
  double blur_sigma = 0.5;   // px
  double noise_sigma = 2.0;  // grey levels
  double seed_error = 3.0;   // px, uniform in [-e, e] per axis
  double k1 = 0.0;           // radial distortion of both cameras
  bool occlude = false;      // the arm covers 4 of the 10 features from 30 % to 60 % of the run
  double stop_at = -1.0;     // s (< 0: no stop)
  double stop_for = 0.0;     // s
  bool colour = false;       // write BGR PNGs
  // Where this panel sits on the line: the run starts start_offset metres further along
  // the conveyor than the centred run, the door turned by extra_yaw (rad, about camL y),
  // under an overall lighting gain (1: as taught). For acquiring a later panel of a model.
  double start_offset = 0.0;
  double extra_yaw = 0.0;
  double gain = 1.0;
  bool rear_door = false;  // render the rear door (a different panel model)
  std::uint64_t seed = 1;
};

class SequenceError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Renders into a temporary sibling of dir and renames it to dir, so a failed run
// leaves nothing half-written. dir must not exist yet (or be empty). Throws
// SequenceError on bad options or I/O failure.
void write_sequence(const SequenceOptions& options, const std::filesystem::path& dir);

}  // namespace dentmark::sim::stereo
