#pragma once
// A door-like panel as a height field z = f(x, y) in its own frame 'panel' (x along
// the door, y up, z out towards the viewer; metres): double curvature, a character line
// (crease), a handle 100 x 18 mm protruding 18 mm, a window opening, rounded borders,
// optional smooth character lines (steps) in any direction, and planted dents and bumps
// with a cos² profile.

#include <Eigen/Core>
#include <string>
#include <vector>

namespace dentmark::sim::scan {

struct PlantedDefect {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();  // panel x, y (m)
  double diameter = 0.01;                            // full width of the cos² profile (m)
  double height = -1e-4;                             // signed, negative = dent (m)
  // The metal it pushed aside: a ring from its edge out to twice its radius, of the
  // opposite sign, rim x |height| at its crest (0: none). Truth is the core's.
  double rim = 0.0;
  // Where it was placed on purpose: the feature (handle, crease, border, window, lineN)
  // and the gap from its rim to that feature's footprint (m; negative: on it). Empty
  // for defects placed at random.
  std::string beside = {};
  double gap = 0.0;
};

// A character line: a smooth (quintic) step of 'step' metres across 'width', along the
// straight line through 'point' at 'angle' to the panel's x axis; the side its normal
// (-sin, cos) points to is raised by 'step' (negative: lowered). Its footprint is the
// step's width.
struct CharacterLine {
  Eigen::Vector2d point = {0.5, 0.3};  // m, panel x, y
  double angle = 0.0;                  // rad
  double step = 0.003;                 // m, signed
  double width = 0.012;                // m
};

struct PanelShape {
  double width = 1.0;   // m, along x
  double height = 0.8;  // m, along y
  bool handle = true;
  bool crease = true;
  bool window = true;
  double edge_radius = 0.006;  // rounded border (m)
  std::vector<CharacterLine> lines;
};

class DoorPanel {
 public:
  DoorPanel(PanelShape shape, std::vector<PlantedDefect> defects);

  // Surface height at (x, y) including features and defects.
  double z(double x, double y) const;
  // Height without the planted defects (the "good" panel).
  double z_nominal(double x, double y) const;
  // Whether (x, y) is on the panel (not outside, not in the window opening).
  bool inside(double x, double y) const;
  // Distance from (x, y) to the nearest border or window edge (m).
  double edge_distance(double x, double y) const;
  // Distance to the nearest design feature (crease line, handle, borders, window).
  double feature_distance(double x, double y) const;
  // Signed distance from a feature's footprint (negative inside it), m. Features:
  // handle, crease, border, window, and "line0", "line1", ... for shape().lines.
  // Throws std::invalid_argument for a feature the panel does not have.
  double footprint_distance(const std::string& feature, double x, double y) const;
  // The panel's features by name (those footprint_distance knows).
  std::vector<std::string> feature_names() const;
  // Signed offset of (x, y) across character line k (along its normal), m.
  double line_offset(std::size_t k, double x, double y) const;
  // Unit normal of the nominal surface (panel frame).
  Eigen::Vector3d normal(double x, double y) const;

  const PanelShape& shape() const { return shape_; }
  const std::vector<PlantedDefect>& defects() const { return defects_; }

  // Feature geometry, for placing defects and for ground truth.
  double crease_y(double x) const;
  Eigen::Vector2d handle_centre() const { return {0.72 * shape_.width, 0.5 * shape_.height + 0.03}; }
  static constexpr double kHandleLength = 0.100, kHandleWidth = 0.018, kHandleHeight = 0.018;

 private:
  double window_distance(double x, double y) const;  // > 0 outside the opening
  PanelShape shape_;
  std::vector<PlantedDefect> defects_;
};

}  // namespace dentmark::sim::scan
