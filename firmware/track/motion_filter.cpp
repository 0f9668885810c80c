#include "dentmark/firmware/track/motion_filter.h"

#include <cmath>

namespace dentmark::track {
namespace {

Eigen::Matrix3d exp_so3(const Eigen::Vector3d& w) {
  const double a = w.norm();
  if (a < 1e-15) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(a, w / a).toRotationMatrix();
}

Eigen::Vector3d log_so3(const Eigen::Matrix3d& r) {
  const Eigen::AngleAxisd aa(r);
  return aa.axis() * aa.angle();
}

}  // namespace

MotionFilter::MotionFilter(const Eigen::Vector3d& centre, const MotionFilterOptions& options)
    : centre_(centre), options_(options) {
  reset(0.0);
}

Eigen::Matrix<double, 6, 1> MotionFilter::to_params(const Transform& m) const {
  // M p = R (p − c) + c + τ: rotation about the features' centroid, so a small rotation
  // does not masquerade as a large translation.
  Eigen::Matrix<double, 6, 1> p;
  p.head<3>() = log_so3(m.linear());
  p.tail<3>() = m.translation() + m.linear() * centre_ - centre_;
  return p;
}

Transform MotionFilter::from_params(const Eigen::Matrix<double, 6, 1>& p) const {
  Transform m = Transform::Identity();
  m.linear() = exp_so3(p.head<3>());
  m.translation() = p.tail<3>() + centre_ - m.linear() * centre_;
  return m;
}

void MotionFilter::reset(double t0) {
  t_ = t0;
  for (std::size_t i = 0; i < axes_.size(); ++i) {
    Axis& a = axes_[i];
    a = Axis{};
    a.last_t = t0;
    // The first frame defines M = I; its speed is unknown (a line runs at up to ~0.5 m/s).
    a.p00 = i < 3 ? 1e-8 : 1e-8;
    a.p11 = i < 3 ? 0.25 : 0.25;
  }
  restarts_ = 0;
}

Eigen::Matrix<double, 6, 1> MotionFilter::variance() const {
  Eigen::Matrix<double, 6, 1> v;
  for (std::size_t i = 0; i < 6; ++i) v(static_cast<Eigen::Index>(i)) = axes_[i].p00;
  return v;
}

Transform MotionFilter::predict(double t) const {
  Eigen::Matrix<double, 6, 1> p;
  const double dt = t - t_;
  for (std::size_t i = 0; i < 6; ++i) p(static_cast<Eigen::Index>(i)) = axes_[i].x + axes_[i].v * dt;
  return from_params(p);
}

Transform MotionFilter::update(double t, const Transform& measured, const Eigen::Vector3d& sigma_rotation,
                               const Eigen::Vector3d& sigma_translation) {
  const Eigen::Matrix<double, 6, 1> z = to_params(measured);
  const double dt = t - t_;
  if (!options_.enabled || !(dt > 0.0)) {
    for (std::size_t i = 0; i < 6; ++i) {
      Axis& a = axes_[i];
      const double zi = z(static_cast<Eigen::Index>(i));
      if (dt > 0.0) a.v = (zi - a.x) / dt;
      a.x = zi;
      a.last_z = zi;
      a.last_t = t;
    }
    t_ = t;
    return measured;
  }
  Eigen::Matrix<double, 6, 1> out;
  for (std::size_t i = 0; i < 6; ++i) {
    Axis& a = axes_[i];
    const double zi = z(static_cast<Eigen::Index>(i));
    const double sigma = i < 3 ? sigma_rotation(static_cast<Eigen::Index>(i))
                               : sigma_translation(static_cast<Eigen::Index>(i - 3));
    const double r = sigma * sigma;
    const double q = std::pow(i < 3 ? options_.accel_noise_rotation : options_.accel_noise_translation, 2);
    // Predict: constant velocity, white-noise acceleration.
    a.x += a.v * dt;
    const double p00 = a.p00 + dt * (2 * a.p01 + dt * a.p11) + q * dt * dt * dt / 3;
    const double p01 = a.p01 + dt * a.p11 + q * dt * dt / 2;
    const double p11 = a.p11 + q * dt;
    const double nu = zi - a.x;
    const double s = p00 + r;
    if (nu * nu > options_.gate_sigmas * options_.gate_sigmas * s) {
      // The motion changed (stop, jerk): restart from the last two measurements.
      const double dtm = t - a.last_t;
      a.x = zi;
      a.v = dtm > 0 ? (zi - a.last_z) / dtm : 0.0;
      a.p00 = r;
      a.p01 = dtm > 0 ? r / dtm : 0.0;
      a.p11 = dtm > 0 ? 2 * r / (dtm * dtm) : a.p11;
      ++restarts_;
    } else {
      const double k0 = p00 / s, k1 = p01 / s;
      a.x += k0 * nu;
      a.v += k1 * nu;
      a.p00 = p00 - k0 * p00;
      a.p01 = p01 - k0 * p01;
      a.p11 = p11 - k1 * p01;
    }
    a.last_z = zi;
    a.last_t = t;
    out(static_cast<Eigen::Index>(i)) = a.x;
  }
  t_ = t;
  return from_params(out);
}

}  // namespace dentmark::track
