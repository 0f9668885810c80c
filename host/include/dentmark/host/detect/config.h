#pragma once
// Detection settings. One default serves every scan: thresholds are stated relative to
// the scan's measured noise and spacing, sizes in metres.

#include <string>

namespace dentmark::detect {

struct DetectConfig {
  // Finest octree node edge (m). Raised to 2x the measured point spacing on coarse scans.
  double finest_node_size = 0.001;
  // Eq. (3) leaf threshold: a leaf is a feature when its normal spread exceeds
  // sqrt(noise_floor² + feature_angle²), noise_floor = median leaf spread (rad).
  double feature_angle = 0.2;
  // Relative occupancy (eq. 4) floor, as area / node face area (dimensionless).
  double min_occupancy = 0.05;
  // Reference surface: local quadratic over this window (m); robust re-fits.
  double reference_window = 0.064;
  int reference_iterations = 3;
  // Detection: |smoothed deviation| > detection_sigma x its measured noise.
  double detection_sigma = 5.5;
  // Smallest |height| worth reporting (m) and size limits of a defect (m).
  double min_height = 3e-5;
  double min_diameter = 0.003;
  double max_defect_diameter = 0.08;
  // Elongated groups (length/width above max_elongation and longer than min_line_length,
  // m) are lines, not defects.
  double max_elongation = 4.0;
  double min_line_length = 0.025;
  // Side of the square patch for the defect's normal (m).
  double normal_patch = 0.03;
  // Holes: an enclosed region no wider than max_hole_diameter (m) where the scanner saw
  // more than hole_depth (m) behind the skin. Wider enclosed openings are design features.
  double hole_depth = 0.003;
  double max_hole_diameter = 0.02;
  int threads = 0;  // 0: all cores
  // Look for dents and bumps on and beside design features as deviations from the
  // feature's own profile along it (along_feature.h). Off by default: on the scans of
  // tests/host/independent_scans it finds more of them but raises false alarms where
  // the reference leaves blocks and streaks along a smooth step (docs/detection.md §12).
  bool along_features = false;
};

// Reads a YAML file of the fields above (all optional). Throws std::runtime_error
// "FILE: line N: field: problem" on bad input.
DetectConfig load_config(const std::string& path);

}  // namespace dentmark::detect
