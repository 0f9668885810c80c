#pragma once
// Renders a flat chessboard calibration target (the tool's target in the twin,
// docs/calibration.md) as each camera of a stereo rig sees it: every pixel is the
// average of 4 × 4 sub-pixel samples of the board's plane (ray–plane intersection
// through the camera model, distortion included at the pixel centre), then optical
// blur and sensor noise. Corners therefore sit at their true sub-pixel positions.

#include <opencv2/core.hpp>

#include "dentmark/common/geometry/transform.h"
#include "dentmark/sim/stereo/stereo_renderer.h"
#include "dentmark/sim/stereo/stereo_rig.h"

namespace dentmark::sim::calibration {

// COLS × ROWS inner corners, corner (i, j) at (i·square, j·square, 0) in the target
// frame (calibrate::TargetSpec's convention), one white square of border around the
// (COLS + 1) × (ROWS + 1) squares. The square beyond corner 0 is black.
struct ChessboardTarget {
  int cols = 7;
  int rows = 6;
  double square = 0.03;  // m
};

struct TargetImaging {
  double blur_sigma = 0.7;   // optics, pixels (0: none)
  double noise_sigma = 2.0;  // sensor noise, grey levels
  double background = 60.0;  // grey level around the board (the arm, the cell)
  double black = 25.0, white = 215.0;
};

class ChessboardRenderer {
 public:
  ChessboardRenderer(sim::stereo::StereoRig rig, ChessboardTarget target);

  // 8-bit grey image of the board at T_camL_target seen by one eye. The board is
  // drawn from either side (a visibility decision is the caller's).
  cv::Mat render(sim::stereo::Eye eye, const Transform& T_camL_target, const TargetImaging& imaging,
                 cv::RNG& rng) const;

  const sim::stereo::StereoRig& rig() const { return rig_; }
  const ChessboardTarget& target() const { return target_; }

 private:
  sim::stereo::StereoRig rig_;
  ChessboardTarget target_;
  cv::Mat normalized_[2];  // per eye: CV_32FC2 undistorted normalised coordinates of each pixel centre
};

}  // namespace dentmark::sim::calibration
