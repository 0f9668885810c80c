#pragma once
// The reference buffer of paper §IV-A: the macro-features' 3D layout in camL at the
// first frame plus their image templates. Motion is always fitted against it, never
// chained frame to frame, so it cannot drift; its pairwise 3D distances are the
// geometric check that catches a feature that slid onto something else.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <span>
#include <vector>

#include "dentmark/common/geometry/transform.h"
#include "dentmark/firmware/track/template_align.h"

namespace dentmark::track {

struct ReferenceFeature {
  Eigen::Vector3d p_camL = Eigen::Vector3d::Zero();  // at the first frame, m
  GridTemplate template_left, template_right;        // patches at the first frame
};

class ReferenceBuffer {
 public:
  void add(const ReferenceFeature& feature);
  std::size_t size() const { return features_.size(); }
  const ReferenceFeature& operator[](std::size_t i) const { return features_[i]; }
  std::vector<Eigen::Vector3d> points() const;
  Eigen::Vector3d centroid() const;

  // Geometric consistency: for each feature i with valid[i], the median over the other
  // valid features j of | |p_i − p_j| − |X_i − X_j| |. A rigidly moved layout gives
  // only noise; a mistracked feature stands out. Invalid entries get +inf.
  std::vector<double> distance_disagreement(std::span<const Eigen::Vector3d> current,
                                            const std::vector<bool>& valid) const;

  // Refines the layout as tracking goes. The first frame's triangulation carries each
  // feature's matching error (sub-pixel phase, noise: 0.5-1 mm of depth), which every
  // later motion inherits, and which shows as a jump when the features that averaged it
  // out leave the view. Each well-determined frame's features, mapped back by its
  // motion M (reference → now), are averaged with the first frame's (add_observation);
  // the caller puts the average back onto the first frame's placement (M(0) = I) and
  // sets it (set_points), so only the layout's shape changes.
  void add_observation(const Transform& M_now_ref, std::span<const Eigen::Vector3d> current,
                       const std::vector<bool>& valid);
  std::vector<Eigen::Vector3d> averaged() const;
  void set_points(std::span<const Eigen::Vector3d> p_camL);

 private:
  std::vector<ReferenceFeature> features_;
  std::vector<Eigen::Vector3d> sum_;  // of the observations, first frame included
  std::vector<double> count_;
};

}  // namespace dentmark::track
