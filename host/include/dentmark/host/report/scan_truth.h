#pragma once
// The ground truth of a synthetic scan (sim/scan) as the evaluator reads it.

#include "dentmark/host/report/defects_json.h"
#include "dentmark/sim/scan/sls_scan.h"

namespace dentmark::report {

TruthFile truth_from_scan(const sim::scan::SynthScan& scan);

}  // namespace dentmark::report
