#include "dentmark/sim/scan/truth_file.h"

#include "dentmark/common/json_file.h"

namespace dentmark::sim::scan {
namespace {

constexpr const char* kSchema = "dentmark.truth/1";

double number(const nlohmann::json& j, const char* key, const std::string& where) {
  return json_file::finite_number<TruthFileError>(j, key, where);
}

Eigen::Vector3d point(const nlohmann::json& j, const std::string& where) {
  if (!j.is_array() || j.size() != 3 || !j[0].is_number() || !j[1].is_number() || !j[2].is_number())
    throw TruthFileError(where + ": expected [x, y, z]");
  return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()};
}

const nlohmann::json& array(const nlohmann::json& j, const char* key, const std::string& where) {
  if (!j.contains(key) || !j[key].is_array()) throw TruthFileError(where + "." + key + ": expected an array");
  return j[key];
}

TruthDefect read_defect(const nlohmann::json& j, const std::string& where) {
  if (!j.is_object()) throw TruthFileError(where + ": expected an object");
  TruthDefect d;
  if (!j.contains("class") || !j["class"].is_string())
    throw TruthFileError(where + ".class: expected a string");
  d.defect_class = j["class"].get<std::string>();
  if (d.defect_class != "dent" && d.defect_class != "bump" && d.defect_class != "hole")
    throw TruthFileError(where + ".class: '" + d.defect_class + "' is not dent, bump or hole");
  d.position = point(j.value("position", nlohmann::json()), where + ".position");
  const Eigen::Vector3d n = point(j.value("normal", nlohmann::json()), where + ".normal");
  if (n.norm() < 1e-9) throw TruthFileError(where + ".normal: zero vector");
  d.normal = n.normalized();
  d.diameter = number(j, "diameter", where);
  d.height = number(j, "height", where);
  if (j.contains("feature")) {
    if (!j["feature"].is_string()) throw TruthFileError(where + ".feature: expected a string");
    d.beside = j["feature"].get<std::string>();
    d.gap = number(j, "gap", where);
  }
  return d;
}

TruthFeature read_feature(const nlohmann::json& j, const std::string& where) {
  if (!j.is_object()) throw TruthFileError(where + ": expected an object");
  TruthFeature f;
  f.name = j.value("name", "");
  f.radius = number(j, "radius", where);
  const nlohmann::json& points = array(j, "points", where);
  for (std::size_t i = 0; i < points.size(); ++i)
    f.points.push_back(point(points[i], where + ".points[" + std::to_string(i) + "]"));
  return f;
}

// generator.T_sls_panel (4 rows of 4) and generator.panel_size [width, height].
void read_panel_pose(const nlohmann::json& gen, const std::string& where, TruthFile& t) {
  if (!gen.is_object() || !gen.contains("T_sls_panel")) return;
  const nlohmann::json& rows = gen["T_sls_panel"];
  Eigen::Matrix4d m;
  if (!rows.is_array() || rows.size() != 4)
    throw TruthFileError(where + ".T_sls_panel: expected 4 rows of 4 numbers");
  for (int r = 0; r < 4; ++r) {
    if (!rows[r].is_array() || rows[r].size() != 4)
      throw TruthFileError(where + ".T_sls_panel: expected 4 rows of 4 numbers");
    for (int c = 0; c < 4; ++c) {
      if (!rows[r][c].is_number()) throw TruthFileError(where + ".T_sls_panel: expected 4 rows of 4 numbers");
      m(r, c) = rows[r][c].get<double>();
    }
  }
  const Eigen::Matrix3d rot = m.topLeftCorner<3, 3>();
  if (!(rot.transpose() * rot).isIdentity(1e-6) || rot.determinant() < 0 ||
      !m.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1)))
    throw TruthFileError(where + ".T_sls_panel: not a rigid transform");
  const nlohmann::json& size = gen.value("panel_size", nlohmann::json());
  if (!size.is_array() || size.size() != 2 || !size[0].is_number() || !size[1].is_number() ||
      size[0].get<double>() <= 0 || size[1].get<double>() <= 0)
    throw TruthFileError(where + ".panel_size: expected [width, height] in m, both > 0");
  t.T_sls_panel = Eigen::Isometry3d(m);
  t.panel_width = size[0].get<double>();
  t.panel_height = size[1].get<double>();
}

nlohmann::json vec(const Eigen::Vector3d& v) {
  return nlohmann::json::array({v.x(), v.y(), v.z()});
}

}  // namespace

TruthFile truth_of(const SynthScan& scan, double panel_width, double panel_height, nlohmann::json generator) {
  TruthFile t;
  t.defects = scan.defects;
  t.features = scan.features;
  t.panel_area = scan.panel_area;
  t.T_sls_panel = scan.T_sls_panel;
  t.panel_width = panel_width;
  t.panel_height = panel_height;
  t.generator = std::move(generator);
  return t;
}

TruthFile read_truth_file(const std::string& path) {
  const nlohmann::json root = json_file::read<TruthFileError>(path);
  const std::string where = path + ": field ";
  if (!root.is_object() || root.value("schema", "") != kSchema)
    throw TruthFileError(where + "schema: expected \"" + kSchema + "\"");
  TruthFile t;
  const nlohmann::json& defects = array(root, "defects", path + ": field");
  for (std::size_t i = 0; i < defects.size(); ++i)
    t.defects.push_back(read_defect(defects[i], where + "defects[" + std::to_string(i) + "]"));
  if (root.contains("features")) {
    const nlohmann::json& features = array(root, "features", path + ": field");
    for (std::size_t i = 0; i < features.size(); ++i)
      t.features.push_back(read_feature(features[i], where + "features[" + std::to_string(i) + "]"));
  }
  t.panel_area = number(root, "panel_area", path + ": field");
  if (root.contains("generator")) {
    t.generator = root["generator"];
    read_panel_pose(t.generator, where + "generator", t);
  }
  return t;
}

nlohmann::json truth_to_json(const TruthFile& truth) {
  nlohmann::json j;
  j["schema"] = kSchema;
  j["units"] = "m";
  j["frame"] = "sls";
  j["panel_area"] = truth.panel_area;
  j["generator"] = truth.generator;
  if (truth.T_sls_panel) {
    nlohmann::json rows = nlohmann::json::array();
    for (int r = 0; r < 4; ++r)
      rows.push_back({(*truth.T_sls_panel)(r, 0), (*truth.T_sls_panel)(r, 1), (*truth.T_sls_panel)(r, 2),
                      (*truth.T_sls_panel)(r, 3)});
    j["generator"]["T_sls_panel"] = rows;
    j["generator"]["panel_size"] = {truth.panel_width, truth.panel_height};
  }
  j["defects"] = nlohmann::json::array();
  int id = 1;
  for (const TruthDefect& d : truth.defects) {
    j["defects"].push_back({{"id", id++},
                            {"class", d.defect_class},
                            {"position", vec(d.position)},
                            {"normal", vec(d.normal)},
                            {"diameter", d.diameter},
                            {"height", d.height}});
    if (!d.beside.empty()) j["defects"].back()["feature"] = d.beside, j["defects"].back()["gap"] = d.gap;
  }
  j["features"] = nlohmann::json::array();
  for (const TruthFeature& f : truth.features) {
    nlohmann::json points = nlohmann::json::array();
    for (const Eigen::Vector3d& p : f.points) points.push_back(vec(p));
    j["features"].push_back({{"name", f.name}, {"radius", f.radius}, {"points", points}});
  }
  return j;
}

}  // namespace dentmark::sim::scan
