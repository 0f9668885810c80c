#pragma once
// The ground truth of a synthetic scan, schema "dentmark.truth/1" (docs/detection.md):
// written by `dentmark synth scan --truth`, read by `dentmark scan evaluate` and by the
// station twin (`dentmark-edge simulate --truth`). Coordinates are in the scanner frame
// 'sls', in metres.

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "dentmark/sim/scan/sls_scan.h"

namespace dentmark::sim::scan {

class TruthFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct TruthFile {
  std::vector<TruthDefect> defects;
  std::vector<TruthFeature> features;
  double panel_area = 0.0;  // m², scanned surface
  // Where the scanned door lies and its size (generator.T_sls_panel, generator.panel_size):
  // present in the files of `dentmark synth scan`, absent in hand-made ones.
  std::optional<Eigen::Isometry3d> T_sls_panel;
  double panel_width = 0.0, panel_height = 0.0;         // m, with T_sls_panel
  nlohmann::json generator = nlohmann::json::object();  // how the scan was made (seed, spacing, ...)
};

// The truth of a synthesized scan; 'generator' records how it was made.
TruthFile truth_of(const SynthScan& scan, double panel_width, double panel_height,
                   nlohmann::json generator = nlohmann::json::object());

// Reads a truth file. Throws TruthFileError "FILE: byte N: ..." or "FILE: field F: ...".
TruthFile read_truth_file(const std::string& path);

// The file's JSON (what read_truth_file reads back).
nlohmann::json truth_to_json(const TruthFile& truth);

}  // namespace dentmark::sim::scan
