#include "dentmark/sim/stereo/stereo_renderer.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

namespace dentmark::sim::stereo {
namespace {

// One straight edge of a convex polygon: outward unit normal m and offset c, so
// m·p − c > 0 outside.
struct Edge {
  Eigen::Vector2d m;
  double c;
};

std::vector<Edge> edges_of(const std::vector<Eigen::Vector2d>& poly) {
  double area2 = 0.0;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const auto& a = poly[i];
    const auto& b = poly[(i + 1) % poly.size()];
    area2 += a.x() * b.y() - b.x() * a.y();
  }
  std::vector<Edge> edges;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const auto& a = poly[i];
    const auto& b = poly[(i + 1) % poly.size()];
    const Eigen::Vector2d d = (b - a).normalized();
    Eigen::Vector2d m(d.y(), -d.x());  // outward for counter-clockwise (area2 > 0) polygons
    if (area2 < 0.0) m = -m;
    edges.push_back({m, m.dot(a)});
  }
  return edges;
}

const PinholeCamera& camera(const StereoRig& rig, Eye eye) {
  return eye == Eye::kLeft ? rig.left : rig.right;
}

Transform T_cam_camL(const StereoRig& rig, Eye eye) {
  return eye == Eye::kLeft ? Transform::Identity() : rig.T_camR_camL;
}

cv::Point2d project_cam(const PinholeCamera& cam, const Eigen::Vector3d& p) {
  std::vector<cv::Point3d> obj{{p.x(), p.y(), p.z()}};
  std::vector<cv::Point2d> img;
  cv::projectPoints(obj, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), cam.K, cam.D, img);
  return img[0];
}

}  // namespace

StereoRenderer::StereoRenderer(StereoRig rig, DoorModel door) : rig_(std::move(rig)), door_(std::move(door)) {
  for (int e = 0; e < 2; ++e) {
    normalized_[e] = normalized_pixel_grid(camera(rig_, static_cast<Eye>(e)), rig_.size);
  }
}

cv::Point2d StereoRenderer::project(Eye eye, const Transform& T_camL_panel,
                                    const Eigen::Vector3d& p_panel) const {
  return project_cam(camera(rig_, eye), T_cam_camL(rig_, eye) * T_camL_panel * p_panel);
}

cv::Mat StereoRenderer::render(Eye eye, const Transform& T_camL_panel, const RenderConditions& conditions,
                               cv::RNG& rng) const {
  const PinholeCamera& cam = camera(rig_, eye);
  const Transform T_cam_panel = T_cam_camL(rig_, eye) * T_camL_panel;
  // Normalised image coordinates of the plane z = 0: n ~ H (x, y, 1), H = [r1 r2 t].
  Eigen::Matrix3d h;
  h.col(0) = T_cam_panel.linear().col(0);
  h.col(1) = T_cam_panel.linear().col(1);
  h.col(2) = T_cam_panel.translation();
  const Eigen::Matrix3d hi = h.inverse();
  const double inv_fx = 1.0 / cam.K(0, 0), inv_fy = 1.0 / cam.K(1, 1);

  cv::Mat1f img(rig_.size);
  for (int v = 0; v < img.rows; ++v)
    for (int u = 0; u < img.cols; ++u)
      img(v, u) = static_cast<float>(door_.background * (0.8 + 0.4 * v / img.rows));

  const cv::Rect frame_rect(cv::Point(0, 0), rig_.size);
  for (const PanelShape& shape : door_.layers) {
    const std::vector<Edge> edges = edges_of(shape.polygon);
    // Image bounding box of the polygon, so only nearby pixels are visited.
    double u0 = 1e9, v0 = 1e9, u1 = -1e9, v1 = -1e9;
    for (const auto& q : shape.polygon) {
      const Eigen::Vector3d pc = T_cam_panel * Eigen::Vector3d(q.x(), q.y(), 0.0);
      if (pc.z() <= 0.0) continue;
      const cv::Point2d px = project_cam(cam, pc);
      u0 = std::min(u0, px.x), u1 = std::max(u1, px.x), v0 = std::min(v0, px.y), v1 = std::max(v1, px.y);
    }
    if (u1 < u0) continue;
    const cv::Rect box = cv::Rect(cv::Point(static_cast<int>(std::floor(std::max(u0 - 4, -1.0))),
                                            static_cast<int>(std::floor(std::max(v0 - 4, -1.0)))),
                                  cv::Point(static_cast<int>(std::ceil(std::min(u1 + 5, 1e6))),
                                            static_cast<int>(std::ceil(std::min(v1 + 5, 1e6))))) &
                         frame_rect;
    // Pixels per metre across each edge, from the homography's Jacobian at the shape's
    // centre (it varies by a few per cent over a shape: the ramp stays symmetric).
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    for (const auto& q : shape.polygon) centre += q;
    centre /= static_cast<double>(shape.polygon.size());
    const Eigen::Vector3d nh = h * Eigen::Vector3d(centre.x(), centre.y(), 1.0);
    Eigen::Matrix2d j;
    j << (hi(0, 0) - centre.x() * hi(2, 0)) * inv_fx, (hi(0, 1) - centre.x() * hi(2, 1)) * inv_fy,
        (hi(1, 0) - centre.y() * hi(2, 0)) * inv_fx, (hi(1, 1) - centre.y() * hi(2, 1)) * inv_fy;
    j *= nh.z();
    std::vector<double> em_x, em_y, ec;
    for (const Edge& e : edges) {
      const double inv = 1.0 / (j.transpose() * e.m).norm();
      em_x.push_back(e.m.x() * inv), em_y.push_back(e.m.y() * inv), ec.push_back(e.c * inv);
    }
    const double h00 = hi(0, 0), h01 = hi(0, 1), h02 = hi(0, 2), h10 = hi(1, 0), h11 = hi(1, 1),
                 h12 = hi(1, 2), h20 = hi(2, 0), h21 = hi(2, 1), h22 = hi(2, 2);
    for (int v = box.y; v < box.y + box.height; ++v) {
      const cv::Vec2f* nrow = normalized_[static_cast<int>(eye)].ptr<cv::Vec2f>(v);
      float* irow = img.ptr<float>(v);
      for (int u = box.x; u < box.x + box.width; ++u) {
        const double nx = nrow[u][0], ny = nrow[u][1];
        const double az = h20 * nx + h21 * ny + h22;
        if (az <= 0.0) continue;
        const double x = (h00 * nx + h01 * ny + h02) / az, y = (h10 * nx + h11 * ny + h12) / az;
        double coverage = 1.0;
        for (std::size_t k = 0; k < edges.size(); ++k) {
          const double d_pix = em_x[k] * x + em_y[k] * y - ec[k];
          coverage *= std::clamp(0.5 - d_pix, 0.0, 1.0);
          if (coverage <= 0.0) break;
        }
        if (coverage <= 0.0) continue;
        const double value = shape.intensity + shape.gradient.x() * x + shape.gradient.y() * y;
        irow[u] = static_cast<float>(irow[u] * (1.0 - coverage) + value * coverage);
      }
    }
  }

  if (conditions.occluder) {
    // The arm: a shaded round bar, drawn by its distance to the projected axis.
    const Occluder& o = *conditions.occluder;
    const Eigen::Vector3d a = T_cam_camL(rig_, eye) * o.a, b = T_cam_camL(rig_, eye) * o.b;
    if (a.z() > 0.05 && b.z() > 0.05) {
      const cv::Point2d pa = project_cam(cam, a), pb = project_cam(cam, b);
      const double r = o.radius * cam.K(0, 0) / (0.5 * (a.z() + b.z()));
      const cv::Point2d ab = pb - pa;
      const double len2 = std::max(ab.dot(ab), 1e-12);
      const cv::Rect box = cv::Rect(cv::Point(static_cast<int>(std::min(pa.x, pb.x) - r - 2),
                                              static_cast<int>(std::min(pa.y, pb.y) - r - 2)),
                                    cv::Point(static_cast<int>(std::max(pa.x, pb.x) + r + 3),
                                              static_cast<int>(std::max(pa.y, pb.y) + r + 3))) &
                           frame_rect;
      for (int v = box.y; v < box.y + box.height; ++v)
        for (int u = box.x; u < box.x + box.width; ++u) {
          const cv::Point2d q(u - pa.x, v - pa.y);
          const double s = std::clamp(q.dot(ab) / len2, 0.0, 1.0);
          const cv::Point2d off = q - s * ab;
          const double d = std::sqrt(off.dot(off));
          const double coverage = std::clamp(r - d + 0.5, 0.0, 1.0);
          if (coverage <= 0.0) continue;
          const double rel = std::min(d / r, 1.0);
          const double value = o.intensity * (1.0 - 0.35 * rel * rel);
          img(v, u) = static_cast<float>(img(v, u) * (1.0 - coverage) + value * coverage);
        }
    }
  }

  img = img * conditions.gain + conditions.offset;
  return expose_8bit(img, conditions.blur_sigma, conditions.noise_sigma, rng);
}

}  // namespace dentmark::sim::stereo
