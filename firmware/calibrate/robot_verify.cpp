#include "dentmark/firmware/calibrate/robot_verify.h"

#include <cmath>
#include <cstdio>

namespace dentmark::calibrate {

VerifyResult verify_robot_calibration(const RobotSamples& s, const Transform& T_base_camL, int poses_planned,
                                      double tolerance_m) {
  VerifyResult v;
  v.poses_planned = poses_planned;
  v.poses_measured = static_cast<int>(s.samples.size());
  v.tolerance_m = tolerance_m;
  double sum = 0.0;
  std::size_t n = 0;
  for (const RobotSample& r : s.samples) {
    double pose_sum = 0.0;
    for (std::size_t j = 0; j < s.target_points_tool.size() && j < r.points_camL.size(); ++j) {
      pose_sum += (T_base_camL * r.points_camL[j] - r.T_base_tool * s.target_points_tool[j]).squaredNorm();
      ++n;
    }
    const double e =
        std::sqrt(pose_sum / static_cast<double>(std::max<std::size_t>(1, r.points_camL.size())));
    v.pose_rms_m.push_back(e);
    v.max_pose_m = std::max(v.max_pose_m, e);
    sum += pose_sum;
  }
  v.rms_m = n > 0 ? std::sqrt(sum / static_cast<double>(n)) : 0.0;
  char b[200];
  if (v.poses_measured == 0) {
    v.reason = "the target was not found at any of the " + std::to_string(poses_planned) +
               " poses where the stored calibration puts it in view";
  } else if (v.poses_measured < poses_planned) {
    std::snprintf(b, sizeof b,
                  "the target was found at only %d of %d poses where the stored calibration puts it in view",
                  v.poses_measured, poses_planned);
    v.reason = b;
  } else if (v.rms_m > tolerance_m) {
    std::snprintf(b, sizeof b, "point transfer RMS %.3f mm over %d poses > tolerance %.3f mm", v.rms_m * 1e3,
                  v.poses_measured, tolerance_m * 1e3);
    v.reason = b;
  }
  v.holds = v.reason.empty();
  return v;
}

}  // namespace dentmark::calibrate
