#pragma once
// The door seen by the tracking cameras: a flat panel drawn as layered convex
// polygons (body, window frame, glass, handle, character line). Its macro-features are
// the window frame corners (paper §IV-A chooses such structural corners).
//
// Panel frame: origin at the door's centre, x along the door (the conveyor's
// direction), y downwards, z into the panel; the visible surface is z = 0. Metres.

#include <Eigen/Core>
#include <vector>

namespace dentmark::sim::stereo {

struct PanelShape {
  std::vector<Eigen::Vector2d> polygon;                // convex, either winding
  double intensity = 0.0;                              // grey level (0..255) at the panel origin
  Eigen::Vector2d gradient = Eigen::Vector2d::Zero();  // grey levels per metre
};

struct DoorModel {
  double background = 45.0;                         // the line behind the door
  std::vector<PanelShape> layers;                   // painted in order
  std::vector<Eigen::Vector2d> features;            // window frame corners (10)
  std::vector<Eigen::Vector2d> lower_panel_points;  // where motion errors are measured
};

// Two models of the line: the front door (the default) and a rear door whose window has
// a different outline (a panel model taught on one must not lock onto the other).
enum class DoorKind { kFront = 0, kRear = 1 };

DoorModel make_door(DoorKind kind = DoorKind::kFront);

}  // namespace dentmark::sim::stereo
