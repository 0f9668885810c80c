#include "dentmark/firmware/plan/marking_pose.h"

#include <cmath>

namespace dentmark::plan {

Transform defect_frame(const Eigen::Vector3d& centre_sls, const Eigen::Vector3d& normal_sls) {
  if (!centre_sls.allFinite() || !normal_sls.allFinite())
    throw GeometryError("defect_frame: non-finite input");
  const double n = normal_sls.norm();
  if (!(n > 1e-9)) throw GeometryError("defect_frame: zero normal");
  const Eigen::Vector3d z = normal_sls / n;
  // Project the scan's x axis onto the plane; fall back to y when x is nearly along z.
  Eigen::Vector3d ref = Eigen::Vector3d::UnitX();
  if (std::abs(z.dot(ref)) > 0.9) ref = Eigen::Vector3d::UnitY();
  const Eigen::Vector3d x = (ref - z.dot(ref) * z).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d r;
  r << x, y, z;
  Transform t = Transform::Identity();
  t.linear() = r;
  t.translation() = centre_sls;
  return t;
}

Transform tool_in_defect_frame(double standoff) {
  if (!std::isfinite(standoff) || standoff < 0.0) throw GeometryError("tool_in_defect_frame: bad standoff");
  // Columns are the tool axes in O_v: x_T = Y_v, y_T = X_v, z_T = −Z_v (det +1).
  Eigen::Matrix3d r;
  r << 0, 1, 0,  //
      1, 0, 0,   //
      0, 0, -1;
  Transform t = Transform::Identity();
  t.linear() = r;
  t.translation() = Eigen::Vector3d(0, 0, standoff);
  return t;
}

Transform tool_pose_in_base(const MarkingChain& chain, const Transform& M_camL, const Transform& T_sls_v) {
  return chain.T_base_camL * M_camL * chain.T_camL_sls * T_sls_v * tool_in_defect_frame(chain.standoff);
}

}  // namespace dentmark::plan
