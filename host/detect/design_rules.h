#pragma once
// What makes a candidate part of the panel's design (a handle, a character line, an edge
// or opening) rather than a defect: its shape, and its place next to one that is.

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "dentmark/host/detect/config.h"
#include "dentmark/host/detect/height_map.h"

namespace dentmark::detect {

struct CandidateShape {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();  // centre (column, row), pixels
  double length = 0.0, width = 0.0;                // along its principal axes (m)
  double area = 0.0;                               // of surface (m²)
  bool touches_edge = false;                       // reaches the border zone
};

// Principal axes of the pixels' cloud (4 sigma + one pixel each way).
CandidateShape shape_of(const std::vector<std::int32_t>& pixels, const HeightMap& map,
                        const cv::Mat& border_zone);

// Why a candidate of this shape is part of the design, or nullptr when it is not.
const char* design_reason(const CandidateShape& shape, const DetectConfig& cfg);

// design: CV_8U, 255 on the pixels of candidates that are part of the design; pixel:
// the map's pixel size (m). Returns 255 on the pixels within 8 mm of them (CV_8U).
cv::Mat design_surroundings(const cv::Mat& design, double pixel);

// The same, with the design candidates that touch a border (border_design, CV_8U) apart:
// their band, the pixels within 25 mm of the border zone (edge_zone, CV_8U), is the
// roll-off of a rolled edge that the reference cannot follow, not a feature with
// shoulders, and only 2 mm around it belong to it (of dents and bumps 16-18 mm from such
// an edge, 0 in 20 were found, all "next to" it; with 2 mm, 12 in 20). The rest of them
// (a crease or a handle that runs into the border's candidate) keeps its 8 mm.
cv::Mat design_surroundings(const cv::Mat& design, const cv::Mat& border_design, const cv::Mat& edge_zone,
                            double pixel);

// Pieces next to a design feature (the rim around a handle, the shoulders of a crease)
// belong to it: a reference surface cannot follow them there. A piece of one lies mostly
// within 8 mm of it or peaks there (a handle's rim is strongest at the handle); a defect
// whose edge merely reaches into the wide, shallow band a crease leaves in the deviation
// keeps its own peak. deviation: CV_32F (m).
bool next_to_design(const std::vector<std::int32_t>& pixels, const cv::Mat& surroundings,
                    const cv::Mat& deviation);

}  // namespace dentmark::detect
