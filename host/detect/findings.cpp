#include "findings.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <numbers>
#include <stdexcept>
#include <utility>

#include "patch_normal.h"

namespace dentmark::detect {

Finding hole_finding(const HoleRegion& hole, const HeightMap& map, const std::vector<float>& ref,
                     const cv::Mat& hole_zone, double normal_patch) {
  const int rows = map.rows, cols = map.cols;
  const double h = map.pixel;
  Finding f;
  f.pixels = static_cast<int>(hole.pixels.size());
  protocol::Defect& d = f.defect;
  d.defect_class = protocol::DefectClass::kHole;
  double su = 0.0, sv = 0.0, sw = 0.0;
  int nw = 0;
  for (auto k : hole.pixels) {
    su += map.u0 + (k % cols + 0.5) * h, sv += map.v0 + (k / cols + 0.5) * h;
    if (std::isfinite(ref[static_cast<std::size_t>(k)]) && map.weight[static_cast<std::size_t>(k)] > 0.0f)
      sw += ref[static_cast<std::size_t>(k)], ++nw;
  }
  const double n = static_cast<double>(hole.pixels.size());
  const double pu = su / n, pv = sv / n;
  const long pk = map.pixel_of(pu, pv);
  const int pr = pk >= 0 ? static_cast<int>(pk / cols) : hole.pixels.front() / cols,
            pc = pk >= 0 ? static_cast<int>(pk % cols) : hole.pixels.front() % cols;
  if (nw == 0) {  // no see-through pixel carries the reference: the skin around it
    const int rad = static_cast<int>(std::ceil(0.5 * hole.diameter / h)) + 3;
    for (int r = std::max(0, pr - rad); r <= std::min(rows - 1, pr + rad); ++r)
      for (int c = std::max(0, pc - rad); c <= std::min(cols - 1, pc + rad); ++c) {
        const int k = r * cols + c;
        if (map.weight[k] > 0.0f && !hole_zone.data[k]) sw += map.w[k], ++nw;
      }
  }
  d.position = map.to_scan(pu, pv, nw > 0 ? sw / nw : 0.0);
  d.normal = patch_normal(map, normal_patch, pr, pc, hole_zone);
  d.diameter = hole.diameter;
  d.area = disc_area(hole.diameter);
  d.height = 0.0;  // no surface to measure
  d.score = 1.0 - std::exp(-static_cast<double>(hole.behind) / 4.0);
  char why[96];
  std::snprintf(why, sizeof why, "through-hole: inner structure seen %.0f mm behind the skin",
                1e3 * hole.backdrop_depth);
  f.reason = why;
  return f;
}

namespace {

// A dent pushes the metal around it up into a low ring (and a bump has a trough around
// it): a candidate of the opposite sign, wider and shallower, around the defect. Seen
// in part (an arc above the threshold), its centre is off the defect's, but within the
// ring's reach (the defect's diameter) and its own radius. It is the same defect,
// reported once.
bool is_rim_of(const protocol::Defect& rim, const protocol::Defect& core, double apart) {
  using protocol::DefectClass;
  const auto raised = [](const protocol::Defect& d) { return d.defect_class == DefectClass::kBump; };
  const auto sunk = [](const protocol::Defect& d) { return d.defect_class == DefectClass::kDent; };
  return ((raised(rim) && sunk(core)) || (sunk(rim) && raised(core))) && rim.diameter > core.diameter &&
         std::abs(rim.height) < std::abs(core.height) && apart < core.diameter && apart < 0.5 * rim.diameter;
}

}  // namespace

namespace {

// Every pixel label of the detection's maps.
template <typename F>
void for_each_label(Detection& out, F&& f) {
  const auto each = [&](std::vector<std::int32_t>& labels) {
#pragma omp parallel for schedule(static)
    for (std::size_t k = 0; k < labels.size(); ++k) f(labels[k]);
  };
  each(out.labels);
  for (auto& chart : out.more_charts) each(chart.labels);
}

}  // namespace

void order_findings(Detection& out) {
  std::stable_sort(out.defects.begin(), out.defects.end(),
                   [](const Finding& a, const Finding& b) { return a.defect.score > b.defect.score; });
  // Labels hold pre-sort indices (kept in id until now).
  std::vector<std::int32_t> old_to_new(out.defects.size());
  for (std::size_t i = 0; i < out.defects.size(); ++i) {
    if (out.defects[i].defect.id >= out.defects.size())
      throw std::logic_error("order_findings: a defect's id is not its index");
    old_to_new[out.defects[i].defect.id] = static_cast<std::int32_t>(i);
  }
  std::vector<std::int32_t> merged_into(out.defects.size(), -1);
  std::vector<Finding> kept;
  for (std::size_t i = 0; i < out.defects.size(); ++i) {
    const auto& di = out.defects[i].defect;
    for (std::size_t j = 0; j < kept.size(); ++j) {
      const auto& dj = kept[j].defect;
      const double apart = (di.position - dj.position).norm();
      // i is j split in two, or j's rim: j stays.
      if ((di.defect_class == dj.defect_class && apart < 0.5 * std::max(di.diameter, dj.diameter)) ||
          is_rim_of(di, dj, apart)) {
        merged_into[i] = static_cast<std::int32_t>(j);
        break;
      }
      if (is_rim_of(dj, di, apart)) {  // the rim came first: the defect takes its place
        merged_into[i] = static_cast<std::int32_t>(j);
        kept[j] = std::move(out.defects[i]);
        break;
      }
    }
    if (merged_into[i] < 0) {
      merged_into[i] = static_cast<std::int32_t>(kept.size());
      kept.push_back(std::move(out.defects[i]));
    }
  }
  out.defects = std::move(kept);
  for_each_label(out, [&](std::int32_t& l) {
    if (l >= 0) l = merged_into[static_cast<std::size_t>(old_to_new[static_cast<std::size_t>(l)])];
  });
  std::uint32_t id = 1;
  for (auto& f : out.defects) f.defect.id = id++;
  for (auto& f : out.features) f.defect.id = id++;
}

}  // namespace dentmark::detect
