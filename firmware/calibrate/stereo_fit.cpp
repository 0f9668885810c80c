#include "dentmark/firmware/calibrate/stereo_fit.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "dentmark/common/nth_smallest.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"

namespace dentmark::calibrate {
namespace {

using ObjectSets = std::vector<std::vector<cv::Point3f>>;
using ImageSets = std::vector<std::vector<cv::Point2f>>;

const cv::TermCriteria kCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-7);

int model_flags(DistortionModel m) {
  return m == DistortionModel::kRational ? cv::CALIB_RATIONAL_MODEL : 0;
}

struct PairFit {
  track::StereoCalibration calibration;
  double rms_px = kNaN;
  std::vector<double> view_rms_left, view_rms_right;
};

// Stages 1 and 2 on the views selected by 'use'.
PairFit fit_pair(const std::vector<StereoView>& views, const std::vector<std::size_t>& use, cv::Size size,
                 DistortionModel model) {
  ObjectSets object;
  ImageSets left, right;
  for (std::size_t i : use) {
    object.push_back(views[i].object);
    left.push_back(views[i].left);
    right.push_back(views[i].right);
  }
  const int flags = model_flags(model);
  cv::Mat k1, d1, k2, d2, r, t, e, f, per_view;
  std::vector<cv::Mat> rv, tv;
  PairFit out;
  try {
    cv::calibrateCamera(object, left, size, k1, d1, rv, tv, flags, kCriteria);
    cv::calibrateCamera(object, right, size, k2, d2, rv, tv, flags, kCriteria);
    out.rms_px = cv::stereoCalibrate(object, left, right, k1, d1, k2, d2, size, r, t, e, f, per_view,
                                     flags | cv::CALIB_USE_INTRINSIC_GUESS, kCriteria);
  } catch (const cv::Exception& ex) {
    throw CalibrateError("the stereo fit failed in OpenCV: " + ex.err);
  }
  if (!std::isfinite(out.rms_px)) throw CalibrateError("the stereo fit failed: non-finite RMS");
  track::StereoCalibration& c = out.calibration;
  c.size = size;
  c.left.K = cv::Matx33d(k1);
  c.left.D = d1.reshape(1, 1).clone();
  c.right.K = cv::Matx33d(k2);
  c.right.D = d2.reshape(1, 1).clone();
  Eigen::Matrix3d re;
  Eigen::Vector3d te;
  cv::cv2eigen(r, re);
  cv::cv2eigen(t.reshape(1, 3), te);
  c.T_camR_camL = Transform::Identity();
  c.T_camR_camL.linear() = re;
  c.T_camR_camL.translation() = te;
  for (int i = 0; i < per_view.rows; ++i) {
    out.view_rms_left.push_back(per_view.at<double>(i, 0));
    out.view_rms_right.push_back(per_view.at<double>(i, 1));
  }
  return out;
}

double stereo_view_rms(double left, double right) {
  return std::sqrt(0.5 * (left * left + right * right));
}

// Stage 3: the outlier limit on view errors: max(median + k · 1.4826 · MAD, r · median).
double outlier_limit(const std::vector<double>& errors, const StereoFitOptions& o) {
  const double med = median_of(errors);
  std::vector<double> dev;
  for (double e : errors) dev.push_back(std::abs(e - med));
  const double mad = median_of(dev);
  return std::max(med + o.outlier_mad_factor * kMadToSigma * mad, o.outlier_median_ratio * med);
}

cv::Mat rotation_of(const track::StereoCalibration& c) {
  cv::Mat r;
  cv::eigen2cv(Eigen::Matrix3d(c.T_camR_camL.linear()), r);
  return r;
}
cv::Mat translation_of(const track::StereoCalibration& c) {
  cv::Mat t;
  cv::eigen2cv(Eigen::Vector3d(c.T_camR_camL.translation()), t);
  return t;
}

struct Rectification {
  cv::Mat r1, r2, p1, p2;
};

Rectification rectify(const track::StereoCalibration& c) {
  Rectification out;
  cv::Mat q;
  cv::stereoRectify(cv::Mat(c.left.K), c.left.D, cv::Mat(c.right.K), c.right.D, c.size, rotation_of(c),
                    translation_of(c), out.r1, out.r2, out.p1, out.p2, q, cv::CALIB_ZERO_DISPARITY, -1);
  return out;
}

std::vector<cv::Point2d> rectified_points(const std::vector<cv::Point2f>& px, const cv::Matx33d& k,
                                          const cv::Mat& d, const cv::Mat& r, const cv::Mat& p) {
  std::vector<cv::Point2d> in(px.begin(), px.end()), out;
  cv::undistortPoints(in, out, cv::Mat(k), d, r, p,
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-12));
  return out;
}

// Stages 5 and 6 over the kept views.
void rectified_figures(const std::vector<StereoView>& views, const std::vector<std::size_t>& use,
                       double square_m, StereoFit& fit) {
  const track::StereoCalibration& c = fit.calibration;
  const Rectification rect = rectify(c);
  double sum_dy = 0.0, max_dy = 0.0, sum_d = 0.0;
  std::size_t n_dy = 0, n_d = 0;
  for (std::size_t i : use) {
    const StereoView& v = views[i];
    const auto l = rectified_points(v.left, c.left.K, c.left.D, rect.r1, rect.p1);
    const auto r = rectified_points(v.right, c.right.K, c.right.D, rect.r2, rect.p2);
    cv::Mat xl(2, static_cast<int>(l.size()), CV_64F), xr(2, static_cast<int>(r.size()), CV_64F);
    for (std::size_t j = 0; j < l.size(); ++j) {
      const double dy = std::abs(l[j].y - r[j].y);
      sum_dy += dy;
      max_dy = std::max(max_dy, dy);
      ++n_dy;
      xl.at<double>(0, static_cast<int>(j)) = l[j].x, xl.at<double>(1, static_cast<int>(j)) = l[j].y;
      xr.at<double>(0, static_cast<int>(j)) = r[j].x, xr.at<double>(1, static_cast<int>(j)) = r[j].y;
    }
    cv::Mat h;
    cv::triangulatePoints(rect.p1, rect.p2, xl, xr, h);
    std::vector<cv::Point3d> p(l.size());
    for (int j = 0; j < h.cols; ++j) {
      const double w = h.at<double>(3, j);
      p[static_cast<std::size_t>(j)] = {h.at<double>(0, j) / w, h.at<double>(1, j) / w,
                                        h.at<double>(2, j) / w};
    }
    // Neighbouring corners: one square apart on the board.
    for (std::size_t a = 0; a < p.size(); ++a)
      for (std::size_t b = a + 1; b < p.size(); ++b) {
        const cv::Point3f d = v.object[a] - v.object[b];
        if (std::abs(std::sqrt(d.dot(d)) - square_m) > 1e-6 * square_m + 1e-9) continue;
        sum_d += cv::norm(p[a] - p[b]);
        ++n_d;
      }
  }
  fit.epipolar_rectified_px = n_dy ? sum_dy / static_cast<double>(n_dy) : kNaN;
  fit.epipolar_rectified_max_px = n_dy ? max_dy : kNaN;
  fit.square_given_m = square_m;
  fit.square_measured_m = n_d ? sum_d / static_cast<double>(n_d) : kNaN;
}

std::vector<cv::Point2d> project(const track::CameraModel& cam, const std::vector<cv::Point3f>& obj,
                                 const cv::Vec3d& rvec, const cv::Vec3d& tvec) {
  const std::vector<cv::Point3d> objd(obj.begin(), obj.end());
  std::vector<cv::Point2d> px;
  cv::projectPoints(objd, rvec, tvec, cv::Mat(cam.K), cam.D, px);
  return px;
}

// Residual vector of a board pose (rvec, tvec: board → camL) against both images.
cv::Mat pose_residuals(const track::StereoCalibration& c, const StereoView& v, const cv::Vec3d& rvec,
                       const cv::Vec3d& tvec, const cv::Vec3d& r_rl, const cv::Vec3d& t_rl) {
  cv::Vec3d rvec_r, tvec_r;
  cv::composeRT(rvec, tvec, r_rl, t_rl, rvec_r, tvec_r);
  const auto pl = project(c.left, v.object, rvec, tvec);
  const auto pr = project(c.right, v.object, rvec_r, tvec_r);
  cv::Mat e(static_cast<int>(4 * pl.size()), 1, CV_64F);
  for (std::size_t j = 0; j < pl.size(); ++j) {
    const int k = static_cast<int>(4 * j);
    e.at<double>(k) = pl[j].x - v.left[j].x;
    e.at<double>(k + 1) = pl[j].y - v.left[j].y;
    e.at<double>(k + 2) = pr[j].x - v.right[j].x;
    e.at<double>(k + 3) = pr[j].y - v.right[j].y;
  }
  return e;
}

}  // namespace

double ViewPrediction::rms_px() const {
  return stereo_view_rms(rms_left_px, rms_right_px);
}

ViewPrediction predict_view(const track::StereoCalibration& c, const StereoView& v) {
  // Start from the left camera's PnP pose, then Gauss-Newton (numerical Jacobian, six
  // unknowns) on both cameras' reprojection errors.
  cv::Vec3d rvec, tvec;
  cv::solvePnP(v.object, v.left, cv::Mat(c.left.K), c.left.D, rvec, tvec, false, cv::SOLVEPNP_ITERATIVE);
  cv::Vec3d r_rl, t_rl;
  cv::Rodrigues(rotation_of(c), r_rl);
  t_rl = cv::Vec3d(translation_of(c));
  for (int it = 0; it < 10; ++it) {
    const cv::Mat e = pose_residuals(c, v, rvec, tvec, r_rl, t_rl);
    cv::Mat j(e.rows, 6, CV_64F);
    for (int k = 0; k < 6; ++k) {
      const double h = 1e-7;
      cv::Vec3d r2 = rvec, t2 = tvec;
      (k < 3 ? r2[k] : t2[k - 3]) += h;
      const cv::Mat e2 = pose_residuals(c, v, r2, t2, r_rl, t_rl);
      cv::Mat col = (e2 - e) / h;
      col.copyTo(j.col(k));
    }
    cv::Mat step;
    if (!cv::solve(j, -e, step, cv::DECOMP_SVD)) break;
    for (int k = 0; k < 3; ++k) rvec[k] += step.at<double>(k), tvec[k] += step.at<double>(k + 3);
    if (cv::norm(step) < 1e-12) break;
  }
  const cv::Mat e = pose_residuals(c, v, rvec, tvec, r_rl, t_rl);
  double sl = 0.0, sr = 0.0;
  for (int k = 0; k < e.rows; k += 4) {
    sl += e.at<double>(k) * e.at<double>(k) + e.at<double>(k + 1) * e.at<double>(k + 1);
    sr += e.at<double>(k + 2) * e.at<double>(k + 2) + e.at<double>(k + 3) * e.at<double>(k + 3);
  }
  const double n = static_cast<double>(e.rows / 4);
  ViewPrediction out;
  out.rms_left_px = std::sqrt(sl / n);
  out.rms_right_px = std::sqrt(sr / n);
  return out;
}

StereoFit fit_stereo(const std::vector<StereoView>& views, cv::Size size, double square_m,
                     const StereoFitOptions& o) {
  const int min_views = std::max(o.min_views, 3);
  if (static_cast<int>(views.size()) < min_views)
    throw CalibrateError("the target was found in both images of " + std::to_string(views.size()) +
                         " pairs; at least " + std::to_string(min_views) + " are needed");
  for (const StereoView& v : views)
    if (v.object.size() < 6 || v.left.size() != v.object.size() || v.right.size() != v.object.size())
      throw CalibrateError("view " + v.name + ": fewer than 6 corners seen by both cameras");

  StereoFit fit;
  fit.views.resize(views.size());
  for (std::size_t i = 0; i < views.size(); ++i) fit.views[i].name = views[i].name;

  // Stages 1–3.
  std::vector<std::size_t> use(views.size());
  std::iota(use.begin(), use.end(), std::size_t{0});
  PairFit pair = fit_pair(views, use, size, o.model);
  while (static_cast<int>(use.size()) > min_views) {
    std::vector<double> e;
    for (std::size_t k = 0; k < use.size(); ++k)
      e.push_back(stereo_view_rms(pair.view_rms_left[k], pair.view_rms_right[k]));
    const auto worst_it = std::max_element(e.begin(), e.end());
    const double limit = outlier_limit(e, o);
    if (!(*worst_it > limit)) break;
    const long worst = worst_it - e.begin();
    char why[200];
    std::snprintf(
        why, sizeof why,
        "outlier: view RMS %.3f px over the limit %.3f px (max(median + %.1f x 1.4826 x MAD, %.1f x "
        "median) of %zu views)",
        *worst_it, limit, o.outlier_mad_factor, o.outlier_median_ratio, e.size());
    fit.views[use[static_cast<std::size_t>(worst)]].rejected_because = why;
    use.erase(use.begin() + worst);
    pair = fit_pair(views, use, size, o.model);
  }
  fit.calibration = pair.calibration;
  fit.rms_px = pair.rms_px;
  fit.views_used = static_cast<int>(use.size());
  double sl = 0.0, sr = 0.0, n_pts = 0.0;
  for (std::size_t k = 0; k < use.size(); ++k) {
    ViewFigures& vf = fit.views[use[k]];
    vf.used = true;
    vf.rms_left_px = pair.view_rms_left[k];
    vf.rms_right_px = pair.view_rms_right[k];
    const double n = static_cast<double>(views[use[k]].object.size());
    sl += n * vf.rms_left_px * vf.rms_left_px;
    sr += n * vf.rms_right_px * vf.rms_right_px;
    n_pts += n;
  }
  fit.rms_left_px = std::sqrt(sl / n_pts);
  fit.rms_right_px = std::sqrt(sr / n_pts);
  for (std::size_t i = 0; i < views.size(); ++i) {
    if (fit.views[i].used) continue;
    const ViewPrediction p = predict_view(fit.calibration, views[i]);
    fit.views[i].rms_left_px = p.rms_left_px;
    fit.views[i].rms_right_px = p.rms_right_px;
    fit.views[i].holdout_rms_px = p.rms_px();  // the fit never saw it
  }

  // Stage 4: leave one out.
  if (o.holdout && use.size() >= 4) {
    double s = 0.0, n = 0.0, worst = 0.0;
    for (std::size_t k = 0; k < use.size(); ++k) {
      std::vector<std::size_t> rest = use;
      rest.erase(rest.begin() + static_cast<long>(k));
      const PairFit without = fit_pair(views, rest, size, o.model);
      const double e = predict_view(without.calibration, views[use[k]]).rms_px();
      fit.views[use[k]].holdout_rms_px = e;
      const double m = 2.0 * static_cast<double>(views[use[k]].object.size());
      s += m * e * e;
      n += m;
      worst = std::max(worst, e);
    }
    fit.holdout_rms_px = std::sqrt(s / n);
    fit.holdout_max_view_px = worst;
  }

  rectified_figures(views, use, square_m, fit);
  return fit;
}

}  // namespace dentmark::calibrate
