#include "dentmark/sim/stereo_raytrace/lens.h"

#include <Eigen/Dense>
#include <cmath>

namespace dentmark::sim::raytrace {

Eigen::Vector2d BrownConrady::distort(const Eigen::Vector2d& xy) const {
  const double x = xy.x(), y = xy.y(), r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
  return {x * radial + 2.0 * d[2] * x * y + d[3] * (r2 + 2.0 * x * x),
          y * radial + d[2] * (r2 + 2.0 * y * y) + 2.0 * d[3] * x * y};
}

Eigen::Vector2d BrownConrady::project_normalized(const Eigen::Vector2d& xy) const {
  const Eigen::Vector2d q = distort(xy);
  return {fx * q.x() + cx, fy * q.y() + cy};
}

Eigen::Vector2d BrownConrady::unproject(const Eigen::Vector2d& pixel) const {
  const Eigen::Vector2d target((pixel.x() - cx) / fx, (pixel.y() - cy) / fy);
  Eigen::Vector2d xy = target;
  for (int it = 0; it < 20; ++it) {
    const Eigen::Vector2d r = distort(xy) - target;
    if (r.norm() < 1e-13) break;
    // Jacobian by central differences: the distortion is a low-order polynomial.
    constexpr double h = 1e-7;
    Eigen::Matrix2d j;
    j.col(0) = (distort(xy + Eigen::Vector2d(h, 0)) - distort(xy - Eigen::Vector2d(h, 0))) / (2 * h);
    j.col(1) = (distort(xy + Eigen::Vector2d(0, h)) - distort(xy - Eigen::Vector2d(0, h))) / (2 * h);
    xy -= j.partialPivLu().solve(r);
  }
  return xy;
}

}  // namespace dentmark::sim::raytrace
