#include "dentmark/host/report/defects_json.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "dentmark/common/atomic_file.h"
#include "dentmark/common/json_file.h"

namespace dentmark::report {
namespace {

protocol::DefectClass class_from(const std::string& s, const std::string& where) {
  if (s == "dent") return protocol::DefectClass::kDent;
  if (s == "bump") return protocol::DefectClass::kBump;
  if (s == "hole") return protocol::DefectClass::kHole;
  if (s == "design_feature") return protocol::DefectClass::kDesignFeature;
  if (s == "noise") return protocol::DefectClass::kNoise;
  throw ReportError(where + ": unknown class '" + s + "'");
}

nlohmann::json vec(const Eigen::Vector3d& v) {
  return nlohmann::json::array({v.x(), v.y(), v.z()});
}

nlohmann::json item(const detect::Finding& f) {
  const auto& d = f.defect;
  return {{"id", d.id},
          {"class", class_name(d.defect_class)},
          {"position", vec(d.position)},
          {"normal", vec(d.normal)},
          {"diameter", d.diameter},
          {"height", d.height},
          {"area", d.area},
          {"score", d.score},
          {"reason", f.reason}};
}

double number(const nlohmann::json& j, const char* key, const std::string& where) {
  return json_file::finite_number<ReportError>(j, key, where);
}

Eigen::Vector3d vec3(const nlohmann::json& j, const char* key, const std::string& where) {
  if (!j.contains(key) || !j[key].is_array() || j[key].size() != 3)
    throw ReportError(where + "." + key + ": expected [x, y, z]");
  Eigen::Vector3d v;
  for (int i = 0; i < 3; ++i) {
    if (!j[key][static_cast<std::size_t>(i)].is_number())
      throw ReportError(where + "." + key + ": expected numbers");
    v[i] = j[key][static_cast<std::size_t>(i)].get<double>();
  }
  if (!v.allFinite()) throw ReportError(where + "." + key + ": not finite");
  return v;
}

std::vector<LabelledDefect> items(const nlohmann::json& root, const char* key, const std::string& path) {
  std::vector<LabelledDefect> out;
  if (!root.contains(key)) return out;
  if (!root[key].is_array()) throw ReportError(path + ": field " + key + ": expected an array");
  for (std::size_t i = 0; i < root[key].size(); ++i) {
    const auto& j = root[key][i];
    const std::string where = path + ": field " + key + "[" + std::to_string(i) + "]";
    if (!j.is_object()) throw ReportError(where + ": expected an object");
    LabelledDefect d;
    if (!j.contains("class") || !j["class"].is_string()) throw ReportError(where + ".class: missing");
    d.defect_class = j["class"].get<std::string>();
    d.defect.defect_class = class_from(d.defect_class, where + ".class");
    d.defect.position = vec3(j, "position", where);
    d.defect.normal = j.contains("normal") ? vec3(j, "normal", where) : Eigen::Vector3d::UnitZ();
    d.defect.diameter = number(j, "diameter", where);
    d.defect.height = number(j, "height", where);
    if (j.contains("score")) d.defect.score = number(j, "score", where);
    out.push_back(d);
  }
  return out;
}

}  // namespace

const char* class_name(protocol::DefectClass c) {
  switch (c) {
    case protocol::DefectClass::kDent:
      return "dent";
    case protocol::DefectClass::kBump:
      return "bump";
    case protocol::DefectClass::kHole:
      return "hole";
    case protocol::DefectClass::kDesignFeature:
      return "design_feature";
    case protocol::DefectClass::kNoise:
      return "noise";
  }
  return "noise";
}

nlohmann::json defects_to_json(const detect::Detection& det, const SourceInfo& source) {
  nlohmann::json j;
  j["schema"] = "dentmark.defects/1";
  j["units"] = "m";
  j["frame"] = "sls";
  j["source"] = {{"file", source.file}, {"vertices", source.vertices}, {"triangles", source.triangles}};
  const auto& s = det.stats;
  j["scan"] = {{"surface_area", s.surface_area},
               {"spacing", s.spacing},
               {"finest_node_size", s.leaf_size},
               {"octree_depth", s.depth},
               {"leaves", s.leaves},
               {"normal_noise_floor", s.noise_floor_sigma},
               {"normal_noise_spread", s.noise_floor_spread},
               {"leaf_sigma_threshold", s.leaf_sigma_threshold},
               {"feature_leaves", s.feature_leaves},
               {"feature_groups", s.feature_groups},
               {"deviation_noise", s.deviation_noise},
               {"stray_triangles", s.stray_triangles},
               {"background_area", s.background_area},
               {"charts", s.charts},
               {"rewound_triangles", s.rewound_triangles}};
  j["defects"] = nlohmann::json::array();
  for (const auto& f : det.defects) j["defects"].push_back(item(f));
  j["features"] = nlohmann::json::array();
  for (const auto& f : det.features) j["features"].push_back(item(f));
  nlohmann::json t = nlohmann::json::object();
  for (const auto& [stage, sec] : det.timing) t[stage] = sec;
  j["timing"] = t;
  return j;
}

protocol::DefectList to_defect_list(const detect::Detection& det) {
  protocol::DefectList list;
  list.frame = "sls";
  for (const auto& f : det.defects) list.defects.push_back(f.defect);
  return list;
}

void write_text_file(const std::string& path, const std::string& text) {
  try {
    files::write_atomically(path, text);
  } catch (const files::FileError& e) {
    throw ReportError(e.what());
  }
}

DefectsFile read_defects_json(const std::string& path) {
  const nlohmann::json root = json_file::read<ReportError>(path);
  if (!root.is_object() || root.value("schema", "") != "dentmark.defects/1")
    throw ReportError(path + ": field schema: expected \"dentmark.defects/1\"");
  DefectsFile f;
  f.defects = items(root, "defects", path);
  f.features = items(root, "features", path);
  if (root.contains("scan") && root["scan"].is_object() && root["scan"].contains("surface_area"))
    f.surface_area = number(root["scan"], "surface_area", path + ": field scan");
  return f;
}

}  // namespace dentmark::report
