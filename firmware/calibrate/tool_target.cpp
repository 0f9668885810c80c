#include "dentmark/firmware/calibrate/tool_target.h"

#include <cmath>

#include "dentmark/firmware/calibrate/calibrate_error.h"

namespace dentmark::calibrate {

std::vector<Eigen::Vector3d> ToolTarget::points_tool() const {
  std::vector<Eigen::Vector3d> p;
  for (int id = 0; id < spec.corner_count(); ++id) {
    const cv::Point3f c = spec.corner(id);
    p.push_back(T_tool_target * Eigen::Vector3d(c.x, c.y, c.z));
  }
  return p;
}

Transform parse_pose6(const std::vector<double>& v, const std::string& option) {
  if (v.empty()) return Transform::Identity();
  if (v.size() != 6) throw CalibrateError(option + ": takes 6 numbers: x y z (m) rx ry rz (rad)");
  for (double x : v)
    if (!std::isfinite(x)) throw CalibrateError(option + ": non-finite value");
  const Eigen::Vector3d t(v[0], v[1], v[2]), r(v[3], v[4], v[5]);
  if (t.norm() > 2.0) throw CalibrateError(option + ": the target is over 2 m from the tool point");
  return make_transform_rotvec(r, t);
}

}  // namespace dentmark::calibrate
