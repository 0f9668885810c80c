#include "dentmark/sim/scan/door_panel.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <numbers>
#include <stdexcept>
#include <string>

namespace dentmark::sim::scan {
namespace {

constexpr double kRadiusX = 3.0;         // m, curvature along the door
constexpr double kRadiusY = 1.6;         // m, curvature across it
constexpr double kCreaseSlope = 0.05;    // rad each side: the line's fold is 0.1 rad
constexpr double kCreaseRound = 0.0015;  // m, rounding of the fold
constexpr double kWindowCorner = 0.03;   // m

double smootherstep(double t) {
  t = std::clamp(t, 0.0, 1.0);
  return t * t * t * (t * (6.0 * t - 15.0) + 10.0);
}

double smoothstep(double t) {
  t = std::clamp(t, 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

// Distance outside an axis-aligned rectangle with rounded corners (negative inside).
double rounded_rect_distance(double x, double y, double x0, double x1, double y0, double y1, double r) {
  const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1);
  const double hx = 0.5 * (x1 - x0) - r, hy = 0.5 * (y1 - y0) - r;
  const double qx = std::abs(x - cx) - hx, qy = std::abs(y - cy) - hy;
  return std::hypot(std::max(qx, 0.0), std::max(qy, 0.0)) + std::min(std::max(qx, qy), 0.0) - r;
}

}  // namespace

DoorPanel::DoorPanel(PanelShape shape, std::vector<PlantedDefect> defects)
    : shape_(shape), defects_(std::move(defects)) {}

double DoorPanel::crease_y(double x) const {
  return 0.45 * shape_.height + 0.02 * (x / shape_.width - 0.5);
}

double DoorPanel::window_distance(double x, double y) const {
  if (!shape_.window) return 1e9;
  const double W = shape_.width, H = shape_.height;
  return rounded_rect_distance(x, y, 0.1 * W, 0.9 * W, 0.68 * H, 0.93 * H, kWindowCorner);
}

double DoorPanel::edge_distance(double x, double y) const {
  const double W = shape_.width, H = shape_.height;
  return std::min({x, W - x, y, H - y, window_distance(x, y)});
}

double DoorPanel::line_offset(std::size_t k, double x, double y) const {
  const CharacterLine& l = shape_.lines.at(k);
  return -std::sin(l.angle) * (x - l.point.x()) + std::cos(l.angle) * (y - l.point.y());
}

std::vector<std::string> DoorPanel::feature_names() const {
  std::vector<std::string> out = {"border"};
  if (shape_.handle) out.push_back("handle");
  if (shape_.crease) out.push_back("crease");
  if (shape_.window) out.push_back("window");
  for (std::size_t k = 0; k < shape_.lines.size(); ++k) out.push_back("line" + std::to_string(k));
  return out;
}

double DoorPanel::footprint_distance(const std::string& feature, double x, double y) const {
  const double W = shape_.width, H = shape_.height;
  if (feature == "border") return std::min({x, W - x, y, H - y}) - shape_.edge_radius;
  if (feature == "window" && shape_.window) return window_distance(x, y) - shape_.edge_radius;
  if (feature == "crease" && shape_.crease) return std::abs(y - crease_y(x)) - kCreaseRound;
  if (feature == "handle" && shape_.handle) {
    const Eigen::Vector2d c = handle_centre();
    return rounded_rect_distance(x, y, c.x() - kHandleLength / 2, c.x() + kHandleLength / 2,
                                 c.y() - kHandleWidth / 2, c.y() + kHandleWidth / 2, 0.004);
  }
  if (feature.rfind("line", 0) == 0) {
    const std::size_t k = static_cast<std::size_t>(std::atoi(feature.c_str() + 4));
    if (k < shape_.lines.size()) return std::abs(line_offset(k, x, y)) - 0.5 * shape_.lines[k].width;
  }
  throw std::invalid_argument("the panel has no feature '" + feature + "'");
}

double DoorPanel::feature_distance(double x, double y) const {
  double d = edge_distance(x, y);
  for (std::size_t k = 0; k < shape_.lines.size(); ++k)
    d = std::min(d, std::max(0.0, std::abs(line_offset(k, x, y)) - 0.5 * shape_.lines[k].width));
  if (shape_.crease) d = std::min(d, std::abs(y - crease_y(x)));
  if (shape_.handle) {
    const Eigen::Vector2d c = handle_centre();
    d = std::min(d, rounded_rect_distance(x, y, c.x() - kHandleLength / 2, c.x() + kHandleLength / 2,
                                          c.y() - kHandleWidth / 2, c.y() + kHandleWidth / 2, 0.004));
  }
  return d;
}

bool DoorPanel::inside(double x, double y) const {
  return edge_distance(x, y) >= 0.0;
}

double DoorPanel::z_nominal(double x, double y) const {
  const double W = shape_.width, H = shape_.height;
  double z = -std::pow(x - 0.5 * W, 2) / (2 * kRadiusX) - std::pow(y - 0.5 * H, 2) / (2 * kRadiusY);
  if (shape_.crease) {
    const double t = y - crease_y(x);
    z -= kCreaseSlope * std::sqrt(t * t + kCreaseRound * kCreaseRound);
  }
  for (std::size_t k = 0; k < shape_.lines.size(); ++k) {
    const CharacterLine& l = shape_.lines[k];
    z += l.step * smootherstep(line_offset(k, x, y) / l.width + 0.5);
  }
  if (shape_.handle) {
    const Eigen::Vector2d c = handle_centre();
    const double qx = (x - c.x()) / (kHandleLength / 2), qy = (y - c.y()) / (kHandleWidth / 2);
    const double q = std::pow(std::pow(qx, 4) + std::pow(qy, 4), 0.25);
    z += kHandleHeight * smoothstep((1.0 - q) / 0.2);
  }
  const double d = edge_distance(x, y), re = shape_.edge_radius;
  if (d < re) z -= re - std::sqrt(std::max(0.0, re * re - (re - std::max(d, 0.0)) * (re - std::max(d, 0.0))));
  return z;
}

double DoorPanel::z(double x, double y) const {
  double z = z_nominal(x, y);
  for (const PlantedDefect& d : defects_) {
    const double r = std::hypot(x - d.centre.x(), y - d.centre.y());
    if (r < 0.5 * d.diameter)
      z += d.height * std::pow(std::cos(std::numbers::pi * r / d.diameter), 2);
    else if (r < d.diameter && d.rim > 0.0)
      z -= d.rim * d.height * std::pow(std::sin(std::numbers::pi * (2.0 * r / d.diameter - 1.0)), 2);
  }
  return z;
}

Eigen::Vector3d DoorPanel::normal(double x, double y) const {
  constexpr double e = 1e-5;
  const double gx = (z_nominal(x + e, y) - z_nominal(x - e, y)) / (2 * e);
  const double gy = (z_nominal(x, y + e) - z_nominal(x, y - e)) / (2 * e);
  return Eigen::Vector3d(-gx, -gy, 1.0).normalized();
}

}  // namespace dentmark::sim::scan
