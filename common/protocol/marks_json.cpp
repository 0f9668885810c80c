#include "dentmark/common/protocol/marks_json.h"

#include <cstdio>
#include <nlohmann/json.hpp>

namespace dentmark::protocol {

std::string marks_json(const DefectList& list, const JobOutcome& outcome, bool with_times) {
  using nlohmann::ordered_json;
  ordered_json marks = ordered_json::array();
  int marked = 0;
  for (const Defect& d : list.defects) {
    ordered_json m;
    m["defect_id"] = d.id;
    m["class"] = to_string(d.defect_class);
    const auto it = outcome.marks.find(d.id);
    if (it == outcome.marks.end()) {
      m["outcome"] = nullptr;  // no report came
      marks.push_back(m);
      continue;
    }
    const Mark& k = it->second;
    marked += k.outcome == MarkOutcome::kMarked;
    m["outcome"] = to_string(k.outcome);
    m["reason"] = to_string(k.reason);
    if (with_times) m["time"] = k.time;
    m["tool_position"] = {k.tool_position.x(), k.tool_position.y(), k.tool_position.z()};
    m["estimated_error"] = k.estimated_error;
    marks.push_back(m);
  }
  ordered_json j;
  j["schema"] = "dentmark.marks/1";
  j["job_id"] = list.job_id;
  j["panel_id"] = list.panel_id;
  j["defects"] = list.defects.size();
  j["reported"] = outcome.marks.size();
  j["marked"] = marked;
  j["complete"] = outcome.complete;
  j["all_marked"] = all_marked(list, outcome);
  j["marks"] = marks;
  return j.dump(2) + "\n";
}

std::string marks_table(const DefectList& list, const JobOutcome& outcome) {
  std::string out;
  char line[256];
  std::snprintf(line, sizeof line, "%6s  %-14s  %-8s  %-15s  %26s  %9s\n", "id", "class", "outcome", "reason",
                "tool position x y z (mm)", "est. (mm)");
  out += line;
  for (const Defect& d : list.defects) {
    const auto it = outcome.marks.find(d.id);
    if (it == outcome.marks.end()) {
      std::snprintf(line, sizeof line, "%6u  %-14s  %-8s\n", d.id, to_string(d.defect_class), "(none)");
    } else {
      const Mark& m = it->second;
      if (m.outcome == MarkOutcome::kMarked)
        std::snprintf(line, sizeof line, "%6u  %-14s  %-8s  %-15s  %8.1f %8.1f %8.1f  %9.2f\n", d.id,
                      to_string(d.defect_class), to_string(m.outcome), to_string(m.reason),
                      m.tool_position.x() * 1e3, m.tool_position.y() * 1e3, m.tool_position.z() * 1e3,
                      m.estimated_error * 1e3);
      else
        std::snprintf(line, sizeof line, "%6u  %-14s  %-8s  %-15s\n", d.id, to_string(d.defect_class),
                      to_string(m.outcome), to_string(m.reason));
    }
    out += line;
  }
  return out;
}

}  // namespace dentmark::protocol
