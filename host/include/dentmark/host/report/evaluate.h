#pragma once
// Scores a detection against ground truth: recall per size class, precision, false
// alarms per m², design features reported as defects, position and depth errors.

#include <string>
#include <vector>

#include "dentmark/host/report/defects_json.h"
#include "dentmark/host/report/scan_truth.h"

namespace dentmark::report {

struct SizeClass {
  std::string name;
  double min_diameter = 0.0, min_depth = 0.0;  // truth defects at least this big
  std::string defect_class;                    // only this class ("": dents and bumps)
  int total = 0, found = 0;
  double recall() const { return total > 0 ? static_cast<double>(found) / total : 1.0; }
};

struct Evaluation {
  int truth = 0, reported = 0, matched = 0, false_alarms = 0, on_features = 0;
  int wrong_sign = 0;  // near a true defect but of another kind (dent, bump, hole)
  double area = 0.0;   // m²
  std::vector<SizeClass> classes;
  double mean_position_error = 0.0, max_position_error = 0.0;  // m
  double mean_depth_error = 0.0, max_depth_error = 0.0;        // m
  int depth_within_tolerance = 0;                              // |err| <= max(10 µm, 10 %)
  int depth_matched = 0;                                       // matches with a depth (not holes)
  double recall() const { return truth > 0 ? static_cast<double>(matched) / truth : 1.0; }
  double precision() const { return reported > 0 ? static_cast<double>(matched) / reported : 1.0; }
  double false_alarms_per_m2() const { return area > 0 ? false_alarms / area : 0.0; }

  void add(const Evaluation& other);  // pools several scans
};

// A reported defect matches a truth defect of the same sign within max(5 mm, diameter/2)
// of its position, measured along the surface (across the truth normal).
Evaluation evaluate(const TruthFile& truth, const DefectsFile& detected);

std::string format_evaluation(const Evaluation& e);

}  // namespace dentmark::report
