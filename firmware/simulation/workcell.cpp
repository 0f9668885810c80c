#include "dentmark/firmware/simulation/workcell.h"

#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>

namespace dentmark::simulation {
namespace {

// A calibration's error: a small random rigid motion (σ per axis), turning about the
// point where its target was seen (the working volume's centre, in the frame the error
// acts in). A calibration is fitted to observations there, so that is where it is best
// known; its rotation error moves points in proportion to their distance from there,
// not from the frame's origin (camL sits 2.8 m from the door).
Transform calibration_error(std::mt19937_64& rng, double sigma_t, double sigma_r,
                            const Eigen::Vector3d& pivot) {
  std::normal_distribution<double> n(0.0, 1.0);
  const Transform about_origin = make_transform_rotvec(sigma_r * Eigen::Vector3d(n(rng), n(rng), n(rng)),
                                                       sigma_t * Eigen::Vector3d(n(rng), n(rng), n(rng)));
  Transform to_pivot = Transform::Identity(), from_pivot = Transform::Identity();
  to_pivot.translation() = pivot;
  from_pivot.translation() = -pivot;
  return to_pivot * about_origin * from_pivot;
}

}  // namespace

Workcell make_workcell(const ScenarioOptions& o, const Transform& T_sls_scanpanel, double scan_width,
                       double scan_height) {
  if (o.position != 'A' && o.position != 'B' && o.position != 'C')
    throw std::invalid_argument("scenario position must be A, B or C");
  Workcell cell;
  const double toe_in = std::atan(0.5 * o.baseline / o.distance);
  cell.rig = sim::stereo::make_rig({o.width, o.height}, o.focal_px, o.baseline, toe_in);
  cell.door = sim::stereo::make_door();

  // The sled turned by the paper's θ about the vertical (camL y) axis: both the door
  // and the direction it travels turn with it.
  const Eigen::Matrix3d yaw = Eigen::AngleAxisd(o.yaw, Eigen::Vector3d::UnitY()).toRotationMatrix();
  cell.motion.speed = o.line_speed;
  cell.motion.vibration = o.vibration;
  cell.motion.direction = yaw * Eigen::Vector3d::UnitX();
  // The door travels from A (scan) past C while the last defects are marked, about
  // 0.9 m; B sits left of where the two views overlap so that the whole run, not just
  // A..C, stays in both views as long as it can.
  const Eigen::Vector3d centre_B(0.5 * o.baseline - 0.17, 0.1, o.distance);
  Transform pose0 = Transform::Identity();
  pose0.linear() = yaw;
  pose0.translation() = centre_B - o.position_spacing * cell.motion.direction;
  cell.motion.T_camL_panel0 = pose0;
  cell.t_mark = (o.position - 'A') * o.position_spacing / o.line_speed;

  // Scan panel (corner origin, y up, z out of the skin) onto the rendered door (centre
  // origin, y down, z into the door): turn half a revolution about x, centre the lower panel.
  cell.T_door_scanpanel =
      make_transform_rotvec(Eigen::Vector3d(std::numbers::pi, 0, 0), Eigen::Vector3d(0.0, 0.1, 0.0)) *
      make_transform_rotvec(Eigen::Vector3d::Zero(),
                            Eigen::Vector3d(-0.5 * scan_width, -0.5 * scan_height, 0.0));
  cell.T_camL_sls_true = pose0 * cell.T_door_scanpanel * T_sls_scanpanel.inverse();

  // Robot base 0.6 m in front of the door at B, axes along camL (z towards the door).
  cell.T_base_camL_true =
      make_transform_rotvec(Eigen::Vector3d::Zero(), -(centre_B - Eigen::Vector3d(0, 0, 0.6)));
  cell.robot_home = make_transform_rotvec(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.0, 0.0, 0.25));
  cell.workspace_min = Eigen::Vector3d(-1.2, -0.8, 0.0);
  cell.workspace_max = Eigen::Vector3d(1.2, 0.8, 1.0);

  std::mt19937_64 rng(o.seed * 7919 + static_cast<std::uint64_t>(o.position) * 31 +
                      static_cast<std::uint64_t>(std::llround(o.yaw * 1e6)));
  // Both calibrations' targets stood at the door's middle position (B).
  cell.T_base_camL_est = calibration_error(rng, o.calibration_translation, o.calibration_rotation,
                                           cell.T_base_camL_true * centre_B) *
                         cell.T_base_camL_true;
  cell.T_camL_sls_est = calibration_error(rng, o.calibration_translation, o.calibration_rotation, centre_B) *
                        cell.T_camL_sls_true;
  return cell;
}

BasePoint true_in_base(const Workcell& cell, const Eigen::Vector3d& p_sls, const Eigen::Vector3d& n_sls,
                       double t) {
  const Transform T_base_sls = cell.T_base_camL_true * cell.motion.motion(t) * cell.T_camL_sls_true;
  return {T_base_sls * p_sls, T_base_sls.linear() * n_sls};
}

}  // namespace dentmark::simulation
