#include "dentmark/firmware/track/reference_buffer.h"

#include <algorithm>
#include <limits>

#include "dentmark/common/nth_smallest.h"

namespace dentmark::track {

void ReferenceBuffer::add(const ReferenceFeature& feature) {
  features_.push_back(feature);
  sum_.push_back(feature.p_camL);
  count_.push_back(1.0);
}

void ReferenceBuffer::add_observation(const Transform& M_now_ref, std::span<const Eigen::Vector3d> current,
                                      const std::vector<bool>& valid) {
  const Transform back = M_now_ref.inverse();
  for (std::size_t i = 0; i < features_.size(); ++i)
    if (valid[i]) sum_[i] += back * current[i], count_[i] += 1.0;
}

std::vector<Eigen::Vector3d> ReferenceBuffer::averaged() const {
  std::vector<Eigen::Vector3d> mean(features_.size());
  for (std::size_t i = 0; i < features_.size(); ++i) mean[i] = sum_[i] / count_[i];
  return mean;
}

void ReferenceBuffer::set_points(std::span<const Eigen::Vector3d> p_camL) {
  for (std::size_t i = 0; i < features_.size() && i < p_camL.size(); ++i) features_[i].p_camL = p_camL[i];
}

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
    out[i] = median_in_place(d);
  }
  return out;
}

}  // namespace dentmark::track
