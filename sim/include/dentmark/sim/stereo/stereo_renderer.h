#pragma once
// Renders the door as each camera of the rig sees it. Edges are anti-aliased by the
// pixel's coverage (a one-pixel box filter across each edge), so corners sit at their
// true sub-pixel positions; then optical blur, lighting gain and sensor noise.

#include <opencv2/core.hpp>
#include <optional>

#include "dentmark/common/geometry/transform.h"
#include "dentmark/sim/stereo/door_model.h"
#include "dentmark/sim/stereo/stereo_rig.h"

namespace dentmark::sim::stereo {

enum class Eye { kLeft = 0, kRight = 1 };

// A round bar (the robot's arm) in front of the panel, camL coordinates.
struct Occluder {
  Eigen::Vector3d a = Eigen::Vector3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  double radius = 0.06;      // m
  double intensity = 150.0;  // grey level on its axis
};

struct RenderConditions {
  double gain = 1.0;  // lighting: grey = gain * scene + offset
  double offset = 0.0;
  double blur_sigma = 0.5;   // optics, pixels (0: none)
  double noise_sigma = 2.0;  // sensor noise, grey levels
  std::optional<Occluder> occluder;
};

class StereoRenderer {
 public:
  StereoRenderer(StereoRig rig, DoorModel door);

  // An 8-bit grey image of the door at pose T_camL_panel seen by one eye.
  cv::Mat render(Eye eye, const Transform& T_camL_panel, const RenderConditions& conditions,
                 cv::RNG& rng) const;

  // Pixel position of a panel point in one eye (with distortion).
  cv::Point2d project(Eye eye, const Transform& T_camL_panel, const Eigen::Vector3d& p_panel) const;

  const StereoRig& rig() const { return rig_; }
  const DoorModel& door() const { return door_; }

 private:
  StereoRig rig_;
  DoorModel door_;
  cv::Mat normalized_[2];  // per eye: CV_32FC2 undistorted normalised coordinates of each pixel
};

}  // namespace dentmark::sim::stereo
