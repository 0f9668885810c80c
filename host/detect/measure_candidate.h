#pragma once
// A dent or bump candidate measured on its own (docs/detection.md §8): against a local
// reference fitted to the clean ring of panel around it, its peak, its half-height
// region, its apex height from the scan's own samples, and its centre.

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "dentmark/common/ingest/mesh_view.h"
#include "dentmark/host/detect/apex_fit.h"
#include "dentmark/host/detect/height_map.h"
#include "dentmark/host/detect/reference_surface.h"

namespace dentmark::detect {

// What every candidate is measured in.
struct CandidateScene {
  const ingest::MeshView& mesh;
  const HeightMap& map;
  const ReferenceSurface& reference;  // the global reference (its last fit)
  const std::vector<float>& ref;      // its heights per pixel (NaN: none)
  const cv::Mat& not_ring;            // CV_8U: never in a ring (candidates, spikes, borders, holes)
  const cv::Mat& spikes;              // CV_8U: never a peak, never measured
  const cv::Mat& labels;              // CV_32S: the candidates' labels
  const PixelSamples& samples;        // the scan's samples under the candidates
  double spacing = 0.0;               // of the scan's samples (m)
  double deviation_noise = 0.0;       // robust sigma of the deviation (m)
  double min_height = 0.0;            // the smallest defect height (m)
  bool coarse = false;                // a pixel holds only one or two samples
};

struct Measurement {
  double peak_deviation = 0.0;                         // smoothed deviation at the peak, signed (m)
  double height = 0.0;                                 // at the apex, signed: negative for a depression (m)
  double half_radius = 0.0;                            // equivalent radius of the half-height region (m)
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // map coordinates (m)
  std::int32_t peak = 0;                               // the peak's pixel
  // The ring is not a smooth panel: the candidate lies between design features.
  bool rough_surroundings = false;
  // On a coarse scan, one vertex alone stands out, far beyond the noise: an outlier.
  bool single_sample = false;
};

// pixels: the candidate's (label 'label' in scene.labels); length: its longer axis (m);
// mean: its centre (column, row).
Measurement measure_candidate(const CandidateScene& scene, const std::vector<std::int32_t>& pixels, int label,
                              double length, const Eigen::Vector2d& mean);

}  // namespace dentmark::detect
