#include "dentmark/sim/stereo/door_model.h"

namespace dentmark::sim::stereo {

DoorModel make_door(DoorKind kind) {
  using V = Eigen::Vector2d;
  DoorModel door;
  // Door skin: bright paint, shaded across by the panel's curvature.
  door.layers.push_back(
      {{V(-0.56, -0.52), V(0.56, -0.52), V(0.58, 0.56), V(-0.56, 0.56)}, 165.0, V(18.0, -12.0)});
  // Window frame (dark seal) and the glass inside it: 5 + 5 corners, the macro-features.
  std::vector<V> frame = {V(-0.50, -0.05), V(-0.50, -0.30), V(-0.30, -0.48), V(0.50, -0.48), V(0.50, -0.05)};
  std::vector<V> glass = {V(-0.46, -0.09), V(-0.46, -0.285), V(-0.285, -0.44), V(0.46, -0.44),
                          V(0.46, -0.09)};
  if (kind == DoorKind::kRear) {
    // Square at the front, the slant at the rear (glass inset 4 cm like the front door).
    frame = {V(-0.50, -0.05), V(-0.50, -0.48), V(0.20, -0.48), V(0.50, -0.20), V(0.50, -0.05)};
    glass = {V(-0.46, -0.09), V(-0.46, -0.44), V(0.183, -0.44), V(0.46, -0.181), V(0.46, -0.09)};
  }
  door.layers.push_back({frame, 38.0, V(0.0, 0.0)});
  door.layers.push_back({glass, 100.0, V(25.0, 30.0)});
  // Character line below the window and the handle: structure that is not a feature.
  door.layers.push_back(
      {{V(-0.54, 0.10), V(0.55, 0.08), V(0.55, 0.095), V(-0.54, 0.115)}, 140.0, V(0.0, 0.0)});
  door.layers.push_back({{V(0.28, 0.16), V(0.42, 0.16), V(0.42, 0.19), V(0.28, 0.19)}, 75.0, V(0.0, 0.0)});
  door.features = frame;
  door.features.insert(door.features.end(), glass.begin(), glass.end());
  for (double y : {0.20, 0.32, 0.45})
    for (double x : {-0.45, -0.15, 0.15, 0.45}) door.lower_panel_points.emplace_back(x, y);
  return door;
}

}  // namespace dentmark::sim::stereo
