#pragma once
// The ground truth of a synthetic scan (sim/scan, its file dentmark.truth/1) as the
// evaluator reads it: labelled defects and design features.

#include <vector>

#include "dentmark/host/report/defects_json.h"
#include "dentmark/sim/scan/truth_file.h"

namespace dentmark::report {

struct TruthFile {
  std::vector<LabelledDefect> defects;
  std::vector<sim::scan::TruthFeature> features;
  double panel_area = 0.0;
};

TruthFile truth_for_evaluation(const sim::scan::TruthFile& truth);
TruthFile truth_from_scan(const sim::scan::SynthScan& scan);

}  // namespace dentmark::report
