#include "dentmark/host/ingest/units.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "dentmark/common/nth_smallest.h"

namespace dentmark::ingest {
namespace {

constexpr std::size_t kSamples = 20000;

}  // namespace

ScaleEvidence measure_scale(const MeshView& mesh) {
  ScaleEvidence e;
  const std::size_t nv = mesh.vertex_count();
  if (nv > 0) {
    // Percentiles per axis: a few outliers thrown metres away do not make the scan big.
    std::vector<double> axis[3];
    const std::size_t stride = std::max<std::size_t>(1, nv / kSamples);
    for (std::size_t i = 0; i < nv; i += stride) {
      const Eigen::Vector3f p = mesh.vertex(i);
      if (!p.allFinite()) continue;
      for (int a = 0; a < 3; ++a) axis[a].push_back(p[a]);
    }
    double d2 = 0.0;
    for (auto& values : axis) {
      if (values.empty()) break;
      // Two selections, not a sort: the same percentiles in a fraction of the time.
      const auto at = [&](std::size_t percent) {
        return nth_smallest(values, values.size() * percent / 100);
      };
      const double lo = at(2), hi = at(98);
      d2 += (hi - lo) * (hi - lo);
    }
    e.extent = std::sqrt(d2);
  }
  e.spacing = point_spacing(mesh);
  return e;
}

double point_spacing(const MeshView& mesh, const std::function<bool(std::size_t)>& use) {
  const std::size_t n = mesh.triangle_count(), stride = std::max<std::size_t>(1, n / 50000);
  std::vector<double> e((n + stride - 1) / stride, std::numeric_limits<double>::quiet_NaN());
  // (Each sample is a few cache misses: chunks to whichever thread is free.)
#pragma omp parallel for schedule(dynamic, 512)
  for (std::size_t j = 0; j < e.size(); ++j) {
    if (use && !use(j * stride)) continue;
    const auto t = mesh.triangle(j * stride);
    const Eigen::Vector3f a = mesh.vertex(t[0]), b = mesh.vertex(t[1]), c = mesh.vertex(t[2]);
    e[j] = static_cast<double>(std::min({(a - b).norm(), (b - c).norm(), (c - a).norm()}));
  }
  if (use) std::erase_if(e, [](double x) { return std::isnan(x); });
  return median_in_place(e);
}

bool looks_like_millimetres(const ScaleEvidence& e) {
  return e.extent > 20.0 || e.spacing > 0.05;
}

}  // namespace dentmark::ingest
