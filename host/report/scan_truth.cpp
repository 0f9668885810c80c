#include "dentmark/host/report/scan_truth.h"

namespace dentmark::report {

TruthFile truth_for_evaluation(const sim::scan::TruthFile& truth) {
  TruthFile t;
  t.panel_area = truth.panel_area;
  t.features = truth.features;
  for (const sim::scan::TruthDefect& d : truth.defects) {
    LabelledDefect l;
    l.defect_class = d.defect_class;
    l.defect.defect_class = d.defect_class == "dent"   ? protocol::DefectClass::kDent
                            : d.defect_class == "bump" ? protocol::DefectClass::kBump
                                                       : protocol::DefectClass::kHole;
    l.defect.position = d.position;
    l.defect.normal = d.normal;
    l.defect.diameter = d.diameter;
    l.defect.height = d.height;
    t.defects.push_back(l);
  }
  return t;
}

TruthFile truth_from_scan(const sim::scan::SynthScan& scan) {
  return truth_for_evaluation(sim::scan::truth_of(scan, 0.0, 0.0));
}

}  // namespace dentmark::report
