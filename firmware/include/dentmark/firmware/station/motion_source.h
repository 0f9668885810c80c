#pragma once
// Where the job runner gets the panel's motion from: the tracker on live cameras, a
// replayed sequence, or the simulator's truth. Motion is M(t) in camL relative to the
// source's own start: p_camL(t) = M(t) · p_camL(t_start).

#include <optional>
#include <string>

#include "dentmark/common/geometry/transform.h"

namespace dentmark::station {

struct MotionEstimate {
  double t = 0.0;  // s, the clock's time of the frame
  Transform M_camL = Transform::Identity();
  bool ok = false;
  double quality = 0.0;         // 0..1 (tracker's figure)
  double expected_error = 0.0;  // m: the tracker's expected error of M_camL (0: not given)
  int features = 0;
  double rms = 0.0;  // m, fit residual
};

class MotionSource {
 public:
  virtual ~MotionSource() = default;
  // Brings the source up to the clock's present and returns its newest estimate;
  // nullopt before the first.
  virtual std::optional<MotionEstimate> latest() = 0;
  // Motion predicted at time t (constant velocity from the newest estimates).
  virtual Transform predict(double t) = 0;
  // Why the source can give no more estimates now (its cameras deliver no frames), or
  // nullopt. The job runner takes it as an interlock and goes safe at once, instead of
  // coasting on the last estimate until it is too old.
  virtual std::optional<std::string> failure() const { return std::nullopt; }
};

}  // namespace dentmark::station
