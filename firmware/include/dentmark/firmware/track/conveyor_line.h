#pragma once
// The conveyor's line: a panel on a conveyor travels along a straight line, so the
// translation of its features' centroid since the first frame lies on a line through
// the origin (design.md §4). The direction is estimated over the run from the measured
// translations (their principal axis); the reported translation is the measured one
// projected onto that line. What leaves the line is stereo noise, mostly depth (one
// frame's disparity noise of 0.1 px is about 1 mm at 2.8 m), and the first frame's own
// triangulation error, which every later M(k) inherits: both are across the line, and
// both are dropped. The projection is per frame, so a stop or a start is followed
// without lag; only the direction is averaged. The panel does not turn on the line
// either: the tracker reports no rotation while the filtered rotation stays within a
// gate of one frame's rotation noise (tracker.cpp).

#include <Eigen/Core>
#include <optional>

namespace dentmark::track {

struct ConveyorLineOptions {
  bool enabled = true;
  double min_travel = 0.003;    // m RMS along the line before its direction is trusted
  double min_elongation = 5.0;  // along-line RMS over across-line RMS, likewise
  // The filtered rotation counts as a turn of the panel (and is reported, with the
  // translation unconstrained) beyond this many of one frame's rotation deviations.
  double turn_gate = 4.0;
};

class ConveyorLine {
 public:
  explicit ConveyorLine(ConveyorLineOptions options = {}) : options_(options) {}

  void reset() { n_ = 0, sum_.setZero(), outer_.setZero(); }
  // A measured translation of the centroid (camL, m; not the first frame's zero).
  void add(const Eigen::Vector3d& tau);
  // The line's unit direction, once the travel so far defines it.
  std::optional<Eigen::Vector3d> direction() const;
  // tau moved onto the line through the origin; unchanged while there is no direction.
  Eigen::Vector3d onto_line(const Eigen::Vector3d& tau) const;

 private:
  ConveyorLineOptions options_;
  int n_ = 0;
  Eigen::Vector3d sum_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d outer_ = Eigen::Matrix3d::Zero();
};

}  // namespace dentmark::track
