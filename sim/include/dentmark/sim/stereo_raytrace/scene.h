#pragma once
// The scene the ray-traced stereo renderer sees: a car door on the conveyor (flat
// panel, painted regions with a dark window frame whose 10 corners are the tracker's
// macro-features) and an optional robot arm (a capped cylinder) in front of it.
//
// Panel frame: origin at the door's centre, x along the conveyor, y downwards, z into
// the panel; the visible surface is z = 0. Metres. Reflectances are linear RGB in 0..1.

#include <Eigen/Core>
#include <optional>
#include <vector>

namespace dentmark::sim::raytrace {

struct Region {
  std::vector<Eigen::Vector2d> outline;  // simple polygon, either winding
  Eigen::Vector3f reflectance = Eigen::Vector3f::Zero();
};

struct Door {
  Eigen::Vector3f background = Eigen::Vector3f::Zero();  // the line behind the door
  std::vector<Region> regions;                           // later ones lie on top
  std::vector<Eigen::Vector2d> features;                 // the window frame's corners
  std::vector<Eigen::Vector2d> eval_points;              // where motion errors are measured
};

// A robot arm: a cylinder from a to b (panel frame; it moves with the panel).
struct Arm {
  Eigen::Vector3d a = Eigen::Vector3d::Zero(), b = Eigen::Vector3d::Zero();
  double radius = 0.07;
  Eigen::Vector3f reflectance{0.75f, 0.42f, 0.08f};
};

Door make_door();

// What a ray (panel frame, direction need not be unit) meets first.
struct Hit {
  int region = -1;  // -1 background, 0.. door region, 1000 the arm
  Eigen::Vector3f reflectance = Eigen::Vector3f::Zero();
  float shading = 1.0f;                             // cosine factor (the arm's curvature)
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  // panel frame
};

Hit trace(const Door& door, const std::optional<Arm>& arm, const Eigen::Vector3d& origin,
          const Eigen::Vector3d& direction);

}  // namespace dentmark::sim::raytrace
