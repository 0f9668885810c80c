#include "dentmark/firmware/station/tracking_trust.h"

namespace dentmark::station {

std::optional<std::string> TrackingTrust::doubt(const MotionEstimate& e) const {
  if (!e.ok) return "the tracker lost the panel";
  if (e.quality < min_quality)
    return "quality " + std::to_string(e.quality) + " < " + std::to_string(min_quality) + " (" +
           std::to_string(e.features) + " features, fit rms " + std::to_string(e.rms) + " m)";
  if (e.expected_error > max_expected_error)
    return "expected error " + std::to_string(e.expected_error) + " m > " +
           std::to_string(max_expected_error) + " m";
  return std::nullopt;
}

}  // namespace dentmark::station
