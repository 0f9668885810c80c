#pragma once
// The `dentmark.marks/1` JSON document: a job's outcomes as the host received them
// (docs/protocol.md §10 describes every field). Written by `dentmark send --wait --json`
// and by the station's twin, so that two runs can be compared byte for byte.

#include <string>

#include "dentmark/common/protocol/job_session.h"

namespace dentmark::protocol {

// Marks in the list's defect order; SI units. 'with_times' false leaves out the
// wall-clock fields (`time`), which differ from run to run.
std::string marks_json(const DefectList& list, const JobOutcome& outcome, bool with_times = true);

// A table for people: id, class, outcome, reason, tool position (mm), estimated error (mm).
std::string marks_table(const DefectList& list, const JobOutcome& outcome);

}  // namespace dentmark::protocol
