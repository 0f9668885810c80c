#include "dentmark/firmware/simulation/scan_truth.h"

#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "dentmark/sim/scan/sls_scan.h"

namespace dentmark::simulation {
namespace {

Eigen::Vector3d vec3(const nlohmann::json& j, const std::string& where) {
  if (!j.is_array() || j.size() != 3) throw std::runtime_error(where + ": expected [x, y, z]");
  return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()};
}

}  // namespace

ScanTruth read_scan_truth(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    throw std::runtime_error(path + ": byte " + std::to_string(e.byte) + ": not JSON");
  }
  ScanTruth t;
  if (!j.contains("defects") || !j["defects"].is_array())
    throw std::runtime_error(path + ": no 'defects' array");
  for (std::size_t i = 0; i < j["defects"].size(); ++i) {
    const auto& d = j["defects"][i];
    const std::string where = path + ": defects[" + std::to_string(i) + "]";
    simulation::TruthDefect td;
    td.defect_class = d.value("class", "");
    td.position = vec3(d.at("position"), where + ".position");
    td.normal = vec3(d.at("normal"), where + ".normal").normalized();
    td.diameter = d.value("diameter", 0.0);
    td.height = d.value("height", 0.0);
    t.defects.push_back(td);
  }
  const auto& gen = j.contains("generator") ? j["generator"] : nlohmann::json::object();
  if (gen.contains("T_sls_panel") && gen.contains("panel_size")) {
    Eigen::Matrix4d m;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) m(r, c) = gen["T_sls_panel"][r][c].get<double>();
    t.T_sls_panel.matrix() = m;
    t.panel_width = gen["panel_size"][0].get<double>();
    t.panel_height = gen["panel_size"][1].get<double>();
  } else if (!t.defects.empty()) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero(), n = Eigen::Vector3d::Zero();
    for (const auto& d : t.defects) c += d.position, n += d.normal;
    c /= static_cast<double>(t.defects.size());
    const Eigen::Vector3d z = n.normalized();
    const Eigen::Vector3d x = (Eigen::Vector3d::UnitX() - z.x() * z).normalized();
    Eigen::Matrix3d r;
    r << x, z.cross(x), z;
    t.T_sls_panel = Transform::Identity();
    t.T_sls_panel.linear() = r;
    t.T_sls_panel.translation() = c;
    t.panel_width = t.panel_height = 0.0;
  }
  return t;
}

SimulatedDoor simulated_door(std::uint64_t seed, int defects, double spacing) {
  sim::scan::ScanOptions o;
  o.seed = seed;
  o.spacing = spacing;
  o.defects = defects;
  o.min_diameter = 0.01;
  const sim::scan::SynthScan scan = sim::scan::synthesize_scan(o);
  SimulatedDoor d;
  d.truth.T_sls_panel = scan.T_sls_panel;
  d.truth.panel_width = o.shape.width;
  d.truth.panel_height = o.shape.height;
  d.list.job_id = seed;
  d.list.panel_id = "simulated-door";
  std::uint32_t id = 1;
  for (const auto& t : scan.defects) {
    d.truth.defects.push_back({t.defect_class, t.position, t.normal, t.diameter, t.height});
    protocol::Defect p;
    p.id = id++;
    p.defect_class = t.height < 0 ? protocol::DefectClass::kDent : protocol::DefectClass::kBump;
    p.position = t.position;
    p.normal = t.normal;
    p.diameter = t.diameter;
    p.height = t.height;
    p.score = 1.0;
    d.list.defects.push_back(p);
  }
  return d;
}

}  // namespace dentmark::simulation
