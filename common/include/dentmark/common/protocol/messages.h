#pragma once
// Host <-> edge messages (design.md §6). Plain data in SI units; the byte encoding
// lives in the codec (docs/protocol.md). Positions and normals are in the frame the
// DefectList names (the scan's frame, 'sls', for lists from `dentmark detect`).

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace dentmark::protocol {

enum class DefectClass : std::uint8_t {
  kDent = 0,           // depression
  kBump = 1,           // protrusion: outward ding, weld spatter
  kHole = 2,           // missing surface
  kDesignFeature = 3,  // handle, character line, edge, window opening: never marked
  kNoise = 4,          // rejected candidate
};

struct Defect {
  std::uint32_t id = 0;
  DefectClass defect_class = DefectClass::kDent;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // m, centre of the defect
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();   // unit, out of the surface (30 × 30 mm plane fit)
  double diameter = 0.0;                               // m
  double height = 0.0;                                 // m, signed: negative = depression
  double area = 0.0;                                   // m²
  double score = 0.0;                                  // confidence in [0, 1]
};

struct DefectList {
  std::uint64_t job_id = 0;
  std::string panel_id;
  double scan_time = 0.0;     // s since the Unix epoch (UTC) when the scan was taken
  std::string frame = "sls";  // frame of positions and normals
  std::vector<Defect> defects;
};

}  // namespace dentmark::protocol
