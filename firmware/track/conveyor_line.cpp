#include "dentmark/firmware/track/conveyor_line.h"

#include <Eigen/Eigenvalues>
#include <cmath>

namespace dentmark::track {

void ConveyorLine::add(const Eigen::Vector3d& tau) {
  ++n_;
  sum_ += tau;
  outer_ += tau * tau.transpose();
}

std::optional<Eigen::Vector3d> ConveyorLine::direction() const {
  if (!options_.enabled || n_ < 2) return std::nullopt;
  const Eigen::Vector3d mean = sum_ / n_;
  const Eigen::Matrix3d cov = outer_ / n_ - mean * mean.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  const Eigen::Vector3d ev = es.eigenvalues().cwiseMax(0.0);  // ascending
  if (std::sqrt(ev(2)) < options_.min_travel) return std::nullopt;
  if (ev(2) < options_.min_elongation * options_.min_elongation * ev(1)) return std::nullopt;
  return es.eigenvectors().col(2).normalized();
}

Eigen::Vector3d ConveyorLine::onto_line(const Eigen::Vector3d& tau) const {
  const auto d = direction();
  if (!d) return tau;
  return tau.dot(*d) * *d;
}

}  // namespace dentmark::track
