#pragma once
// JSON defect lists, schema "dentmark.defects/1" (docs/detection.md). Files are
// written to a temporary name and renamed.

#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "dentmark/common/protocol/messages.h"
#include "dentmark/host/detect/detector.h"

namespace dentmark::report {

class ReportError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct SourceInfo {
  std::string file;
  std::size_t vertices = 0, triangles = 0;
};

// "dent", "bump", "hole", "design_feature" or "noise".
const char* class_name(protocol::DefectClass c);

nlohmann::json defects_to_json(const detect::Detection& detection, const SourceInfo& source);
// The defect list for the binary protocol (dent, bump, hole only).
protocol::DefectList to_defect_list(const detect::Detection& detection);

// Atomic write of text. Throws ReportError.
void write_text_file(const std::string& path, const std::string& text);

// A labelled item of a defect or truth file.
struct LabelledDefect {
  std::string defect_class;
  protocol::Defect defect;
};

struct DefectsFile {
  std::vector<LabelledDefect> defects;   // reported defects
  std::vector<LabelledDefect> features;  // reported non-defects
  double surface_area = 0.0;             // m², 0 if absent
};

// Reads a defects JSON ("dentmark.defects/1"). Throws ReportError "FILE: byte N: ..." or
// "FILE: field F: ...".
DefectsFile read_defects_json(const std::string& path);

}  // namespace dentmark::report
