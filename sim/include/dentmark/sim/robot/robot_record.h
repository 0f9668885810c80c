#pragma once
// The simulator's record (tip over time, sprays) as a JSON file for evaluation tools.
// Written to a temporary file and renamed, so a reader never sees half a record.

#include <string>
#include <vector>

#include "dentmark/sim/robot/robot_simulator.h"

namespace dentmark::sim::robot {

// Throws std::runtime_error naming the file when it cannot be written.
// Poses are written as {"t": [x, y, z] (m), "r": [rx, ry, rz] (rotation vector, rad)}.
void write_robot_record(const std::string& path, const std::vector<TipSample>& trajectory,
                        const std::vector<SprayRecord>& sprays);

}  // namespace dentmark::sim::robot
