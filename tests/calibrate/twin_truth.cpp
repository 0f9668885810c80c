// The ground truth side of the live robot calibration's end-to-end test
// (live_robot.sh): writes the twin's calibration scene, and judges a robot.yaml
// against it. Not part of the station: only the test sees the truth.
//   twin_truth scene DIR              DIR/scene.yaml and DIR/cal/stereo.yaml; prints
//                                     the target's pose on the tool (6 numbers)
//   twin_truth check SCENE ROBOT_YAML MAX_M
//       point transfer on 60 held-out poses (not the calibration's), each target
//       point placed by the truth and carried into base with the file's T_base_camL
//       against the truth: RMS ≤ MAX_M exits 0, else 1.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include "../support/rig_calibration.h"
#include "dentmark/firmware/calibrate/calibration_poses.h"
#include "dentmark/firmware/calibrate/robot_calibration_file.h"
#include "dentmark/sim/calibration/calibration_scene.h"

using namespace dentmark;

namespace {

calibrate::ToolTarget target_of(const sim::calibration::CalibrationScene& s) {
  calibrate::ToolTarget t;
  t.spec.kind = calibrate::TargetKind::kChessboard;
  t.spec.cols = s.target.cols;
  t.spec.rows = s.target.rows;
  t.spec.square_m = s.target.square;
  t.T_tool_target = s.T_tool_target;
  return t;
}

int scene(const std::filesystem::path& dir) {
  const sim::calibration::CalibrationScene s = sim::calibration::twin_calibration_scene();
  std::filesystem::create_directories(dir / "cal");
  sim::calibration::write_calibration_scene(s, dir / "scene.yaml");
  sim::stereo::write_stereo_yaml(s.rig, dir / "cal" / "stereo.yaml");
  const Eigen::AngleAxisd aa(s.T_tool_target.linear());
  const Eigen::Vector3d r = aa.angle() * aa.axis(), t = s.T_tool_target.translation();
  std::printf("%.6f %.6f %.6f %.6f %.6f %.6f\n", t.x(), t.y(), t.z(), r.x(), r.y(), r.z());
  return 0;
}

int check(const std::string& scene_file, const std::string& robot_file, double max_m) {
  const sim::calibration::CalibrationScene s = sim::calibration::read_calibration_scene(scene_file);
  const Transform est = calibrate::load_robot_calibration(robot_file);
  const calibrate::ToolTarget target = target_of(s);
  calibrate::PosePlanOptions plan;
  plan.poses = 60;
  plan.workspace_min = Eigen::Vector3d(-0.6, -0.8, -0.1);
  plan.workspace_max = Eigen::Vector3d(0.9, 0.8, 1.2);
  plan.min_separation = 0.05;
  plan.halton_offset = 20000;  // not the calibration's (1…) nor verify's (5000…) poses
  const Transform home =
      make_transform_rotvec(Eigen::Vector3d(3.14159265358979, 0, 0), Eigen::Vector3d(0.4, 0.0, 0.5));
  const auto poses =
      calibrate::plan_calibration_poses(target, test::exact_calibration(s.rig), s.T_base_camL, home, plan);
  double sum = 0.0, worst = 0.0;
  std::size_t n = 0;
  for (const Transform& T_base_tool : poses)
    for (const Eigen::Vector3d& p_tool : target.points_tool()) {
      const Eigen::Vector3d p_camL = s.T_base_camL.inverse() * T_base_tool * p_tool;  // truth
      const double e = (est * p_camL - T_base_tool * p_tool).norm();
      sum += e * e, worst = std::max(worst, e), ++n;
    }
  const double rms = std::sqrt(sum / static_cast<double>(n));
  const Transform d = s.T_base_camL.inverse() * est;
  std::printf(
      "against the truth: point transfer on %zu held-out poses (%zu points): RMS %.3f mm, max %.3f mm; "
      "T_base_camL off by %.3f mm, %.3f mrad\n",
      poses.size(), n, rms * 1e3, worst * 1e3, (est.translation() - s.T_base_camL.translation()).norm() * 1e3,
      Eigen::AngleAxisd(d.linear()).angle() * 1e3);
  return rms <= max_m ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::string cmd = argc > 1 ? argv[1] : "";
    if (cmd == "scene" && argc == 3) return scene(argv[2]);
    if (cmd == "check" && argc == 5) return check(argv[2], argv[3], std::stod(argv[4]));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "twin_truth: %s\n", e.what());
    return 2;
  }
  std::fprintf(stderr, "usage: twin_truth scene DIR | check SCENE ROBOT_YAML MAX_M\n");
  return 2;
}
