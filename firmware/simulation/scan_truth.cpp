#include "dentmark/firmware/simulation/scan_truth.h"

#include "dentmark/sim/scan/sls_scan.h"
#include "dentmark/sim/scan/truth_file.h"

namespace dentmark::simulation {

ScanTruth read_scan_truth(const std::string& path) {
  const sim::scan::TruthFile file = sim::scan::read_truth_file(path);
  ScanTruth t;
  t.defects = file.defects;
  if (file.T_sls_panel) {
    t.T_sls_panel = *file.T_sls_panel;
    t.panel_width = file.panel_width;
    t.panel_height = file.panel_height;
  } else if (!t.defects.empty()) {
    // No pose in the file: the door frame at the defects' centroid, facing their mean normal.
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
    d.truth.defects.push_back(t);
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
