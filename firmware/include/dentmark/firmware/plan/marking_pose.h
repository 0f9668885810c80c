#pragma once
// The pose of the marking tool for one defect (paper §IV-C, eq. 5–6; design.md §2).
//
//   T_base_tool = T_base_camL · M(t) · T_camL_sls · T_sls_v · T_v_tool(standoff)
//
// O_v is the defect frame: origin at the defect centre, Z_v out of the surface plane
// fitted over a 3 × 3 cm patch. The tool's z axis points into the surface and its tip
// stops 'standoff' out along +Z_v.
//
// Paper eq. (5) gives R_TC = [Y_v | −X_v | −Z_v], whose determinant is −1 (a
// reflection: Y_v × (−X_v) = +Z_v, not −Z_v), which no robot can reach. We keep its
// intent — tool z along −Z_v, tool axes aligned with O_v — with the proper rotation
// R_v_tool = [Y_v | X_v | −Z_v] (Y_v × X_v = −Z_v).

#include <Eigen/Core>

#include "dentmark/common/geometry/transform.h"

namespace dentmark::plan {

// The defect frame T_sls_v from the defect centre and the outward unit normal, both in
// the scan frame. X_v is the scan's x axis projected onto the plane (the y axis when x
// is nearly normal to it), so the frame is repeatable for the same input.
// Throws GeometryError on a zero or non-finite normal or a non-finite centre.
Transform defect_frame(const Eigen::Vector3d& centre_sls, const Eigen::Vector3d& normal_sls);

// T_v_tool: tool tip 'standoff' metres out along +Z_v, tool z pointing into the surface.
Transform tool_in_defect_frame(double standoff);

// The chain of eq. (6), generalised to a moving panel. M_camL is the panel's motion in
// camL since the scan (p_camL(t) = M(t) · p_camL(t_scan)).
struct MarkingChain {
  Transform T_base_camL = Transform::Identity();  // robot-to-stereo calibration (paper Q_CB)
  Transform T_camL_sls = Transform::Identity();   // SLS-to-stereo calibration
  double standoff = 0.03;                         // m (paper's safety reserve δ_r)
};

Transform tool_pose_in_base(const MarkingChain& chain, const Transform& M_camL, const Transform& T_sls_v);

}  // namespace dentmark::plan
