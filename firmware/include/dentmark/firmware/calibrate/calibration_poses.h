#pragma once
// The robot poses at which the tool's target is measured (docs/calibration.md).
//
// A rigid fit of T_base_camL is well conditioned when the target's points spread over
// the volume (translation) and the tool turns about all three axes between poses
// (rotation: a target seen under one orientation only leaves the rotation about the
// line of sight weakly determined). The planner draws candidates from a
// low-discrepancy (Halton) sequence: positions inside the workspace limits, shrunk by
// a margin, and orientations turned from the start orientation by up to max_tilt
// about each axis. A candidate is kept when the whole board (with its border) lies
// inside both images with a margin, faces both cameras within max_view_angle, and
// lies at least min_separation from every pose already kept. Where the cameras are
// comes from a prior T_base_camL: the start pose's measurement, or the stored
// calibration (verify). Kept poses are ordered greedily by distance from the start
// (short robot moves).

#include <string>
#include <vector>

#include "dentmark/common/geometry/transform.h"
#include "dentmark/firmware/calibrate/tool_target.h"
#include "dentmark/firmware/track/stereo_calibration.h"

namespace dentmark::calibrate {

struct PosePlanOptions {
  int poses = 20;
  Eigen::Vector3d workspace_min = Eigen::Vector3d::Zero();  // m, base (the board's limits)
  Eigen::Vector3d workspace_max = Eigen::Vector3d::Zero();
  double workspace_margin = 0.05;  // m inside the limits
  double max_tilt = 0.6;           // rad about each axis from the start orientation
  double max_view_angle = 0.96;    // rad (55°) between the board's normal and the line of sight
  double image_margin_px = 25.0;   // the board's outline this far inside both images
  double min_separation = 0.12;    // m between the tool points of two kept poses
  int halton_offset = 1;           // where in the sequence to start (verify uses another stretch)
  int max_candidates = 20000;
};

// Whether the board at T_camL_target is seen whole and from its front by both
// cameras; 'why' says what fails.
bool target_visible(const track::StereoCalibration& stereo, const TargetSpec& target,
                    const Transform& T_camL_target, const PosePlanOptions& options,
                    std::string* why = nullptr);

// Throws CalibrateError when fewer than options.poses visible poses are found (the
// message names the limits to check).
std::vector<Transform> plan_calibration_poses(const ToolTarget& target,
                                              const track::StereoCalibration& stereo,
                                              const Transform& T_base_camL_prior,
                                              const Transform& T_base_tool_start,
                                              const PosePlanOptions& options);

}  // namespace dentmark::calibrate
