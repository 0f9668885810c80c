#pragma once
// Defects on coarse scans, from the vertices (local_surface_fit.h). At 4-6 mm between
// samples a 9 mm defect is one to three vertices standing out of their neighbours'
// surface, and so is a flying pixel. What tells them apart is coherence: a defect lifts
// (or sinks) a group of neighbouring vertices the same way, while a thrown sample stands
// alone among neighbours that lie on the surface. (Direction does not: in a range image
// every sample, a defect's or a thrown one, lies on its own pixel's ray, so a single
// vertex's offset looks the same either way.) A group is the mesh-connected vertices
// over a lower threshold of the same sign, holding one over the detection threshold
// (hysteresis, as Canny's edges); it is a defect when it holds two vertices or more.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "dentmark/common/ingest/mesh_view.h"
#include "dentmark/host/detect/detector.h"

namespace dentmark::detect {

// A coherent group of vertices standing out of the local surface the same way.
struct VertexGroup {
  std::vector<std::uint32_t> vertices;
  std::uint32_t apex = 0;  // the vertex of largest |residual|
  int sign = 0;            // +1 out of the panel (bump), -1 into it (dent)
};

// The groups of 'mesh' (residual: per vertex, m along the normal, NaN: none; excluded:
// per vertex, nonzero where no defect may be, such as on a design feature): connected
// by mesh edges, each member over member_sigmas × sigma with the group's sign, one over
// seed_sigmas × sigma; groups touching an excluded vertex, and lone vertices, left out.
std::vector<VertexGroup> coherent_groups(const ingest::MeshView& mesh, const std::vector<float>& residual,
                                         const std::vector<std::uint8_t>& excluded, double sigma,
                                         double seed_sigmas, double member_sigmas);

// Per vertex, 1 within 'rings' edges of the mesh's boundary (an edge of one triangle: the
// panel's outline, an opening, a dropout), else 0. A rolled edge falls away there, and
// the local surface of a vertex on it is all on one side.
std::vector<std::uint8_t> near_mesh_boundary(const ingest::MeshView& mesh, int rings);

// A group as a finding, in the scan frame: its position the residual-weighted mean of
// its vertices, its height the apex's residual, its diameter 4 × the equivalent radius of
// its vertices over half that height (each standing for spacing² of panel: a cos² profile's
// full width), its normal 'normal' (towards the sensor), its score from the apex's SNR.
Finding coarse_finding(const VertexGroup& group, const ingest::MeshView& mesh,
                       const std::vector<float>& residual, const Eigen::Vector3d& normal, double spacing,
                       double sigma, double detection_sigma);

}  // namespace dentmark::detect
