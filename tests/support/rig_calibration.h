#pragma once
// The tracker's calibration of a rendered rig, exact (tests that want the true one).

#include "dentmark/firmware/track/stereo_calibration.h"
#include "dentmark/sim/stereo/stereo_rig.h"

namespace dentmark::test {

inline track::StereoCalibration exact_calibration(const sim::stereo::StereoRig& rig) {
  track::StereoCalibration c;
  c.size = rig.size;
  c.left.K = rig.left.K;
  c.left.D = rig.left.D.clone();
  c.right.K = rig.right.K;
  c.right.D = rig.right.D.clone();
  c.T_camR_camL = rig.T_camR_camL;
  return c;
}

}  // namespace dentmark::test
