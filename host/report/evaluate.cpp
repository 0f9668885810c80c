#include "dentmark/host/report/evaluate.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace dentmark::report {

void Evaluation::add(const Evaluation& o) {
  const int m0 = matched;
  truth += o.truth, reported += o.reported, matched += o.matched, false_alarms += o.false_alarms;
  on_features += o.on_features, wrong_sign += o.wrong_sign, area += o.area;
  depth_within_tolerance += o.depth_within_tolerance;
  const int dm0 = depth_matched;
  depth_matched += o.depth_matched;
  if (classes.empty())
    classes = o.classes;
  else
    for (std::size_t i = 0; i < classes.size() && i < o.classes.size(); ++i)
      classes[i].total += o.classes[i].total, classes[i].found += o.classes[i].found;
  if (matched > 0) {
    mean_position_error = (mean_position_error * m0 + o.mean_position_error * o.matched) / matched;
  }
  if (depth_matched > 0)
    mean_depth_error = (mean_depth_error * dm0 + o.mean_depth_error * o.depth_matched) / depth_matched;
  max_position_error = std::max(max_position_error, o.max_position_error);
  max_depth_error = std::max(max_depth_error, o.max_depth_error);
}

Evaluation evaluate(const TruthFile& truth, const DefectsFile& det) {
  Evaluation e;
  e.classes = {{"d>=10mm,h>=0.05mm", 0.010, 5e-5, ""},
               {"d>=5mm,h>=0.1mm", 0.005, 1e-4, ""},
               {"holes", 0.0, 0.0, "hole"}};
  // Dents, bumps and holes are different kinds: a match needs the same kind.
  auto kind = [](const std::string& cls, double height) { return cls == "hole" ? 2 : height < 0 ? 0 : 1; };
  e.truth = static_cast<int>(truth.defects.size());
  e.reported = static_cast<int>(det.defects.size());
  e.area = truth.panel_area > 0 ? truth.panel_area : det.surface_area;
  // Greedy matching, closest pairs first; a match needs the same sign.
  struct Pair {
    double dist;
    std::size_t t, d;
  };
  std::vector<Pair> pairs;
  for (std::size_t t = 0; t < truth.defects.size(); ++t)
    for (std::size_t d = 0; d < det.defects.size(); ++d) {
      const auto& td = truth.defects[t].defect;
      // Along the surface: the offset along the normal is the height's business.
      const Eigen::Vector3d off = det.defects[d].defect.position - td.position;
      const Eigen::Vector3d n = td.normal.normalized();
      const double dist = (off - off.dot(n) * n).norm();
      if (dist <= std::max(0.005, 0.5 * td.diameter)) pairs.push_back({dist, t, d});
    }
  std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) { return a.dist < b.dist; });
  std::vector<char> t_used(truth.defects.size(), 0), d_used(det.defects.size(), 0);
  double pos_sum = 0.0, depth_sum = 0.0;
  for (const Pair& p : pairs) {
    if (t_used[p.t] || d_used[p.d]) continue;
    const auto& td = truth.defects[p.t].defect;
    const auto& dd = det.defects[p.d].defect;
    if (kind(truth.defects[p.t].defect_class, td.height) != kind(det.defects[p.d].defect_class, dd.height)) {
      ++e.wrong_sign;
      continue;
    }
    t_used[p.t] = d_used[p.d] = 1;
    ++e.matched;
    pos_sum += p.dist;
    e.max_position_error = std::max(e.max_position_error, p.dist);
    if (truth.defects[p.t].defect_class == "hole") continue;
    ++e.depth_matched;
    const double derr = std::abs(dd.height - td.height);
    depth_sum += derr;
    e.max_depth_error = std::max(e.max_depth_error, derr);
    if (derr <= std::max(10e-6, 0.1 * std::abs(td.height))) ++e.depth_within_tolerance;
  }
  if (e.matched > 0) e.mean_position_error = pos_sum / e.matched;
  if (e.depth_matched > 0) e.mean_depth_error = depth_sum / e.depth_matched;
  for (std::size_t t = 0; t < truth.defects.size(); ++t) {
    const auto& td = truth.defects[t].defect;
    const bool hole = truth.defects[t].defect_class == "hole";
    for (auto& c : e.classes)
      if ((c.defect_class == "hole") == hole && td.diameter >= c.min_diameter - 1e-9 &&
          std::abs(td.height) >= c.min_depth - 1e-12) {
        ++c.total;
        if (t_used[t]) ++c.found;
      }
  }
  for (std::size_t d = 0; d < det.defects.size(); ++d) {
    if (d_used[d]) continue;
    ++e.false_alarms;
    bool near = false;
    for (const auto& f : truth.features)
      for (const auto& p : f.points)
        if ((p - det.defects[d].defect.position).norm() <= f.radius) near = true;
    if (near) ++e.on_features;
  }
  return e;
}

std::string format_evaluation(const Evaluation& e) {
  char buf[2048];
  std::string s;
  std::snprintf(buf, sizeof buf,
                "truth %d, reported %d, matched %d\nrecall %.1f %%, precision %.1f %%\n"
                "false alarms %d (%.3f per m² over %.3f m²), on design features %d, wrong kind %d\n",
                e.truth, e.reported, e.matched, 100 * e.recall(), 100 * e.precision(), e.false_alarms,
                e.false_alarms_per_m2(), e.area, e.on_features, e.wrong_sign);
  s += buf;
  for (const auto& c : e.classes) {
    if (c.total == 0 && !c.defect_class.empty()) continue;  // no holes in the truth
    std::snprintf(buf, sizeof buf, "recall %-20s %.1f %% (%d of %d)\n", c.name.c_str(), 100 * c.recall(),
                  c.found, c.total);
    s += buf;
  }
  std::snprintf(buf, sizeof buf,
                "position error mean %.2f mm, max %.2f mm\ndepth error mean %.1f um, max %.1f um, within "
                "max(10 um, 10 %%): %d of %d\n",
                1e3 * e.mean_position_error, 1e3 * e.max_position_error, 1e6 * e.mean_depth_error,
                1e6 * e.max_depth_error, e.depth_within_tolerance, e.depth_matched);
  s += buf;
  return s;
}

}  // namespace dentmark::report
