#include "dentmark/host/report/scan_truth.h"

namespace dentmark::report {

TruthFile truth_from_scan(const sim::scan::SynthScan& scan) {
  TruthFile truth;
  truth.panel_area = scan.panel_area;
  for (const auto& d : scan.defects) {
    LabelledDefect l;
    l.defect_class = d.defect_class;
    l.defect.position = d.position;
    l.defect.normal = d.normal;
    l.defect.diameter = d.diameter;
    l.defect.height = d.height;
    truth.defects.push_back(l);
  }
  for (const auto& f : scan.features) truth.features.push_back({f.name, f.points, f.radius});
  return truth;
}

}  // namespace dentmark::report
