#pragma once
// Which tracker estimates the station steers by. A distrusted estimate (the tracker lost
// the panel, kept few features or fitted them badly, or is unsure of its motion) is kept
// out of the motion prediction. A job stops at once when the tracker lost the panel; a
// poor or unsure estimate it coasts through on the prediction from the trusted ones
// until the newest trusted estimate is older than JobConfig::max_estimate_age
// (docs/station.md, "Tracking during a job").

#include <optional>
#include <string>

#include "dentmark/firmware/station/motion_source.h"

namespace dentmark::station {

struct TrackingTrust {
  double min_quality = 0.2;          // tracker quality below this: distrusted
  double max_expected_error = 2e-3;  // m: a tracker less sure than this: distrusted

  // Why 'e' is not to be steered by, or nullopt when it is trusted.
  std::optional<std::string> doubt(const MotionEstimate& e) const;
};

}  // namespace dentmark::station
