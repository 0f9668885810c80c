#pragma once
// Depth of a dent or bump at its apex, measured on the scan's own samples. A height-map
// pixel averages a (finest node)² patch, which flattens the apex of a 5 mm defect by
// ~10 %; the vertices under the apex do not.
#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "dentmark/common/ingest/mesh_view.h"
#include "dentmark/host/detect/height_map.h"

namespace dentmark::detect {

// The mesh vertices that fall in selected pixels, in map coordinates, bucketed by pixel.
class PixelSamples {
 public:
  // select: one byte per map pixel, non-zero to keep that pixel's vertices.
  PixelSamples(const ingest::MeshView& mesh, const HeightMap& map, const std::vector<std::uint8_t>& select);
  // Appends the samples of 'pixel' (map coordinates u, v, w) to 'out'.
  void append(std::int32_t pixel, std::vector<Eigen::Vector3d>& out) const;
  std::size_t size() const { return points_.size(); }

 private:
  std::vector<std::int32_t> keys_;  // sorted pixel numbers
  std::vector<Eigen::Vector3f> points_;
};

// A sample near the apex: position in the map plane relative to the apex guess, and its
// signed deviation from the reference surface along the surface normal (m).
struct ApexSample {
  double x = 0.0, y = 0.0, deviation = 0.0;
};

// Signed apex height from a + b x + c y + d r² + e r⁴ fitted by least squares to the
// samples within 'radius' (the quartic term follows the apex's flattening, so the fit
// can use the whole half-height disc). Samples whose residual exceeds 4 robust sigmas
// (outliers, the far wall of a hole) are dropped and the fit repeated. The disc is then
// re-centred on the model's extreme of sign 'sign' (within radius / 2) and refitted
// until it stays put: radial terms only follow the apex when centred on it. Samples
// are relative to the apex guess and should cover 1.5 radius around it. Empty when
// fewer than 12 samples or a degenerate fit.
std::optional<double> fit_apex_height(const std::vector<ApexSample>& samples, double radius, double sign);

// The same over an ellipse for a long defect (a crease-shaped dent): semi-axes 'radius'
// across and stretch × radius along the unit vector 'along'. A disc of the half-height
// area's radius reaches past a 6 mm wide trough's sides onto the panel, and read a
// 40 x 6 mm crease 22-28 % short; the ellipse keeps to its floor. The samples are
// stretched to a disc and fitted as above, without the cone model (round apexes only).
std::optional<double> fit_apex_height(const std::vector<ApexSample>& samples, double radius, double sign,
                                      const Eigen::Vector2d& along, double stretch);

}  // namespace dentmark::detect
