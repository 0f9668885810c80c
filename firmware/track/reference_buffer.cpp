#include "dentmark/firmware/track/reference_buffer.h"

#include <algorithm>
#include <limits>

namespace dentmark::track {

std::vector<Eigen::Vector3d> ReferenceBuffer::points() const {
  std::vector<Eigen::Vector3d> p;
  p.reserve(features_.size());
  for (const auto& f : features_) p.push_back(f.p_camL);
  return p;
}

Eigen::Vector3d ReferenceBuffer::centroid() const {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& f : features_) c += f.p_camL;
  return features_.empty() ? c : Eigen::Vector3d(c / static_cast<double>(features_.size()));
}

std::vector<double> ReferenceBuffer::distance_disagreement(std::span<const Eigen::Vector3d> current,
                                                           const std::vector<bool>& valid) const {
  const std::size_t n = features_.size();
  std::vector<double> out(n, std::numeric_limits<double>::infinity());
  std::vector<double> d;
  for (std::size_t i = 0; i < n; ++i) {
    if (!valid[i]) continue;
    d.clear();
    for (std::size_t j = 0; j < n; ++j) {
      if (j == i || !valid[j]) continue;
      d.push_back(
          std::abs((current[i] - current[j]).norm() - (features_[i].p_camL - features_[j].p_camL).norm()));
    }
    if (d.empty()) continue;
    std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
    out[i] = d[d.size() / 2];
  }
  return out;
}

}  // namespace dentmark::track
