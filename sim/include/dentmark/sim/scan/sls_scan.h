#pragma once
// A structured-light scan of a DoorPanel: a perspective grid of rays from a tilted
// viewpoint, range noise along the ray, sparse outliers, dropouts, meshed on the sensor
// grid. Coordinates in the sensor frame 'sls' (z along the optical axis), metres.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "dentmark/sim/scan/door_panel.h"

namespace dentmark::sim::scan {

struct ScanOptions {
  std::uint64_t seed = 1;
  double spacing = 0.0005;                           // m between samples on the panel
  double noise = 20e-6;                              // m, range noise (1 sigma)
  int defects = 8;                                   // random dents and bumps to plant
  double min_diameter = 0.005, max_diameter = 0.03;  // m
  double min_depth = 5e-5, max_depth = 5e-4;         // m, |height|
  double rim = 0.0;               // random defects' rim (PlantedDefect::rim): the metal pushed aside
  double outlier_fraction = 0.0;  // fraction of points thrown 2..20 mm along the ray
  int dropouts = 0;               // missing discs (specular spots), 2..6 mm radius
  int holes = 0;                  // through-holes (defects), the inner panel seen through them
  double min_hole_diameter = 0.003, max_hole_diameter = 0.015;  // m
  double hole_backdrop = 0.06;                                  // m, inner structure behind the skin
  bool shuffle = false;                                         // triangles (and vertices) in random order
  double standoff = 0.9;                                        // m, sensor to panel centre
  // The sensor's yaw, pitch (about the panel's y and x) and roll (about its own axis), rad;
  // unset: yaw and pitch drawn within 12 degrees, no roll.
  std::optional<Eigen::Vector3d> tilt;
  PanelShape shape;
  std::vector<PlantedDefect> planted;  // explicit defects (added to the random ones)
  // Defects placed beside features: for each gap (m, from the defect's rim to the
  // feature's footprint) one random defect beside every character line (near_lines; a
  // negative gap centres it on the line) or beside every other feature: handle, crease,
  // border, window (near_features). Sizes as the random ones; clear of other features by
  // 25 mm.
  std::vector<double> near_lines;
  std::vector<double> near_features;
};

struct TruthDefect {
  std::string defect_class;  // "dent", "bump" or "hole"
  Eigen::Vector3d position;  // sls, m: the defect's centre on the surface
  Eigen::Vector3d normal;    // sls, unit, towards the sensor
  double diameter = 0.0;     // m
  double height = 0.0;       // m, signed, along the surface normal (0 for a hole)
  // Placed beside a feature on purpose (PlantedDefect::beside, ::gap); empty otherwise.
  std::string beside = {};
  double gap = 0.0;  // m, rim to the feature's footprint; negative: on it
};

// A design feature as sample points along it (sls) and a radius around them.
struct TruthFeature {
  std::string name;  // handle, crease, border, window
  std::vector<Eigen::Vector3d> points;
  double radius = 0.0;
};

struct SynthScan {
  std::vector<Eigen::Vector3f> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;
  std::vector<TruthDefect> defects;
  std::vector<TruthFeature> features;
  double panel_area = 0.0;  // m², scanned surface
  Eigen::Isometry3d T_sls_panel = Eigen::Isometry3d::Identity();
};

// Throws std::invalid_argument on nonsensical options.
SynthScan synthesize_scan(const ScanOptions& options);

}  // namespace dentmark::sim::scan
