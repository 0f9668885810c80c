#pragma once
// The scanned door's ground truth for the station twin: read from `dentmark synth
// scan --truth` (schema dentmark.truth/1), or made directly from the scan simulator.

#include <cstdint>
#include <string>

#include "dentmark/common/protocol/messages.h"
#include "dentmark/firmware/simulation/station_sim.h"

namespace dentmark::simulation {

// Reads a truth file. Without the scan's panel pose (generator.T_sls_panel and
// generator.panel_size) the door frame is placed at the defects' centroid, facing
// their mean normal. Throws std::runtime_error naming the file and field.
ScanTruth read_scan_truth(const std::string& path);

struct SimulatedDoor {
  ScanTruth truth;
  protocol::DefectList list;  // the truth as a perfectly detected defect list
};

// A door from the scan simulator (sim/scan) with 'defects' planted dents and bumps of
// at least 10 mm; 'spacing' only sets how finely the (unused) mesh is sampled.
SimulatedDoor simulated_door(std::uint64_t seed, int defects, double spacing = 0.006);

}  // namespace dentmark::simulation
