#include "dentmark/sim/stereo_raytrace/ray_tracer.h"

#include <algorithm>

namespace dentmark::sim::raytrace {

RayTracer::RayTracer(BrownConrady lens, Eigen::Isometry3d T_camL_cam, cv::Size size, int supersample)
    : lens_(lens), T_camL_cam_(T_camL_cam), size_(size), n_(std::max(1, supersample)) {
  corners_.create(size.height + 1, size.width + 1);
  for (int v = 0; v <= size.height; ++v)
    for (int u = 0; u <= size.width; ++u) {
      const Eigen::Vector2d xy = lens_.unproject({u - 0.5, v - 0.5});
      corners_(v, u) = cv::Vec2d(xy.x(), xy.y());
    }
}

cv::Mat3f RayTracer::render(const Door& door, const std::optional<Arm>& arm,
                            const std::vector<Eigen::Isometry3d>& poses, const Lighting& light) const {
  const int w = size_.width, h = size_.height;
  const std::size_t slots = poses.size();
  // Per exposure instant: the camera centre and rotation in the panel frame.
  std::vector<Eigen::Vector3d> origin(slots);
  std::vector<Eigen::Matrix3d> rot(slots);
  for (std::size_t k = 0; k < slots; ++k) {
    const Eigen::Isometry3d T_panel_cam = poses[k].inverse() * T_camL_cam_;
    origin[k] = T_panel_cam.translation();
    rot[k] = T_panel_cam.linear();
  }
  auto ray = [&](const Eigen::Vector2d& xy, std::size_t k) {
    return trace(door, arm, origin[k], rot[k] * Eigen::Vector3d(xy.x(), xy.y(), 1.0));
  };
  auto radiance = [&](const Hit& hit, std::size_t k) -> Eigen::Vector3f {
    const Eigen::Vector3d p_camL = poses[k] * hit.point;
    return hit.reflectance * static_cast<float>(hit.shading * light.at(p_camL));
  };
  // Which region each pixel corner sees at the start and the end of the exposure.
  cv::Mat1i first(h + 1, w + 1), last(h + 1, w + 1);
  cv::parallel_for_(cv::Range(0, h + 1), [&](const cv::Range& rows) {
    for (int v = rows.start; v < rows.end; ++v)
      for (int u = 0; u <= w; ++u) {
        const Eigen::Vector2d xy(corners_(v, u)[0], corners_(v, u)[1]);
        first(v, u) = ray(xy, 0).region;
        last(v, u) = slots > 1 ? ray(xy, slots - 1).region : first(v, u);
      }
  });
  cv::Mat1b edge(h, w);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      const int r = first(v, u);
      edge(v, u) = (first(v, u + 1) != r || first(v + 1, u) != r || first(v + 1, u + 1) != r ||
                    last(v, u) != r || last(v, u + 1) != r || last(v + 1, u) != r || last(v + 1, u + 1) != r)
                       ? 255
                       : 0;
    }
  // A region's vertex can sit inside a pixel whose corners all miss it: widen by one.
  cv::Mat1b wide(h, w, uchar(0));
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u)
      if (edge(v, u))
        for (int dv = -1; dv <= 1; ++dv)
          for (int du = -1; du <= 1; ++du) {
            const int y = v + dv, x = u + du;
            if (y >= 0 && y < h && x >= 0 && x < w) wide(y, x) = 255;
          }

  cv::Mat3f out(h, w);
  const std::size_t mid = slots / 2;
  const int nn = n_ * n_;
  cv::parallel_for_(cv::Range(0, h), [&](const cv::Range& rows) {
    for (int v = rows.start; v < rows.end; ++v)
      for (int u = 0; u < w; ++u) {
        const cv::Vec2d c00 = corners_(v, u), c01 = corners_(v, u + 1), c10 = corners_(v + 1, u),
                        c11 = corners_(v + 1, u + 1);
        auto at = [&](double a, double b) {  // bilinear inside the pixel (a: across, b: down)
          const cv::Vec2d q = (1 - b) * ((1 - a) * c00 + a * c01) + b * ((1 - a) * c10 + a * c11);
          return Eigen::Vector2d(q[0], q[1]);
        };
        Eigen::Vector3f sum = Eigen::Vector3f::Zero();
        if (!wide(v, u)) {
          sum = radiance(ray(at(0.5, 0.5), mid), mid);
        } else {
          for (int s = 0; s < nn; ++s) {
            const int i = s % n_, j = s / n_;
            // The sub-ray's instant: a permutation of the grid, so time and position decorrelate.
            const std::size_t k =
                static_cast<std::size_t>((s * 37 + 11) % nn) * slots / static_cast<std::size_t>(nn);
            // Every sub-ray at its own column and row of an n² x n² grid (the canonical
            // multi-jittered arrangement): an edge's coverage resolves to 1/n² px, not 1/n.
            sum += radiance(ray(at((i + (j + 0.5) / n_) / n_, (j + (i + 0.5) / n_) / n_), k), k);
          }
          sum /= static_cast<float>(nn);
        }
        out(v, u) = cv::Vec3f(sum.x(), sum.y(), sum.z());
      }
  });
  return out;
}

}  // namespace dentmark::sim::raytrace
