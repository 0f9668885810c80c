#pragma once
// Findings as reported: through-holes turned into findings, and the final order of the
// defect list.

#include <cmath>
#include <numbers>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "dentmark/host/detect/detector.h"
#include "holes.h"

namespace dentmark::detect {

// A defect's area: the disc of its diameter (m²).
inline double disc_area(double diameter) {
  return std::numbers::pi * 0.25 * diameter * diameter;
}

// A defect's score in [0, 1): 1 - exp(-snr / (2 detection_sigma)), snr its peak over the
// noise; a defect at the detection threshold scores 0.39.
inline double score_of(double snr, double detection_sigma) {
  return 1.0 - std::exp(-snr / (2.0 * detection_sigma));
}

// A through-hole as a defect: its centre on the reference surface 'ref' (or, where no
// see-through pixel carries it, on the skin around), its normal from the skin around it
// (hole_zone: CV_8U, the holes and their rims, left out), its equivalent diameter.
Finding hole_finding(const HoleRegion& hole, const HeightMap& map, const std::vector<float>& ref,
                     const cv::Mat& hole_zone, double normal_patch);

// Defects most confident first. One defect split into two candidates (by a dropout, say)
// is reported once: a less confident report of the same class whose centre lies within
// half the larger of the two diameters of a kept one joins it; so does a dent's rim (a
// wider, shallower bump around it: centre within the dent's diameter and the rim's
// radius) or a bump's trough, whichever came first. Ids run from 1 over the
// defects, then the features. On entry each defect's id is its index in
// detection.labels (0 .. defects - 1; std::logic_error otherwise); labels follow.
void order_findings(Detection& detection);

}  // namespace dentmark::detect
