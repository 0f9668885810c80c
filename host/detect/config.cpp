#include "dentmark/host/detect/config.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <functional>
#include <map>
#include <stdexcept>

namespace dentmark::detect {

DetectConfig load_config(const std::string& path) {
  DetectConfig c;
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw std::runtime_error(path + ": cannot read the config file");
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(path + ": line " + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
  if (root.IsNull()) return c;
  if (!root.IsMap()) throw std::runtime_error(path + ": line 1: expected a map of settings");
  // name -> (target, min, max)
  struct Field {
    double* value;
    double lo, hi;
  };
  double iterations = c.reference_iterations, threads = c.threads, along = c.along_features ? 1.0 : 0.0;
  const std::map<std::string, Field> fields = {
      {"finest_node_size", {&c.finest_node_size, 1e-5, 1.0}},
      {"feature_angle", {&c.feature_angle, 0.0, 1.5}},
      {"min_occupancy", {&c.min_occupancy, 0.0, 10.0}},
      {"reference_window", {&c.reference_window, 1e-3, 2.0}},
      {"reference_iterations", {&iterations, 1, 10}},
      {"detection_sigma", {&c.detection_sigma, 1.0, 100.0}},
      {"min_height", {&c.min_height, 0.0, 1.0}},
      {"min_diameter", {&c.min_diameter, 0.0, 1.0}},
      {"max_defect_diameter", {&c.max_defect_diameter, 1e-4, 5.0}},
      {"max_elongation", {&c.max_elongation, 1.0, 1000.0}},
      {"min_line_length", {&c.min_line_length, 0.0, 5.0}},
      {"normal_patch", {&c.normal_patch, 1e-3, 1.0}},
      {"hole_depth", {&c.hole_depth, 1e-4, 1.0}},
      {"max_hole_diameter", {&c.max_hole_diameter, 0.0, 1.0}},
      {"threads", {&threads, 0, 1024}},
      {"along_features", {&along, 0, 1}},
  };
  for (const auto& kv : root) {
    const std::string key = kv.first.as<std::string>();
    const int line = kv.first.Mark().line + 1;
    const auto it = fields.find(key);
    if (it == fields.end())
      throw std::runtime_error(path + ": line " + std::to_string(line) + ": " + key + ": unknown setting");
    double v = 0.0;
    try {
      v = kv.second.as<double>();
    } catch (const YAML::Exception&) {
      throw std::runtime_error(path + ": line " + std::to_string(line) + ": " + key + ": expected a number");
    }
    if (!std::isfinite(v) || v < it->second.lo || v > it->second.hi)
      throw std::runtime_error(path + ": line " + std::to_string(line) + ": " + key + ": out of range [" +
                               std::to_string(it->second.lo) + ", " + std::to_string(it->second.hi) + "]");
    *it->second.value = v;
  }
  c.reference_iterations = static_cast<int>(iterations);
  c.threads = static_cast<int>(threads);
  c.along_features = along != 0.0;
  return c;
}

}  // namespace dentmark::detect
