#include "dentmark/firmware/track/stereo_match.h"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "dentmark/firmware/track/plane_view.h"
#include "dentmark/firmware/track/template_align.h"

namespace dentmark::track {

std::optional<StereoMatch> match_right_to_left(const StereoCalibration& calib, const ImagePyramid& right,
                                               const ImagePyramid& left, const cv::Point2f& p_right,
                                               const StereoMatchOptions& o, const LkOptions& lk) {
  const cv::Mat& imr = right.image();
  const cv::Mat& iml = left.image();
  const int h = o.template_half;
  const GridTemplate grid = grid_template(imr, p_right, h);
  if (grid.patch.empty()) return std::nullopt;
  const cv::Mat& templ = grid.patch;
  // The camR ray of the corner, sampled in inverse depth and seen by camL: the epipolar
  // curve (curved when the lenses distort).
  const cv::Point2d n = calib.normalize(Cam::kRight, {p_right})[0];
  const Eigen::Vector3d ray(n.x, n.y, 1.0);
  const Transform T_camL_camR = calib.T_camR_camL.inverse();
  auto along = [&](double depth) { return Eigen::Vector3d(T_camL_camR * (depth * ray)); };
  const std::vector<cv::Point2f> ends = calib.project(Cam::kLeft, {along(o.min_depth), along(o.max_depth)});
  const double length = cv::norm(ends[0] - ends[1]);
  const int samples = std::clamp(static_cast<int>(length * 1.5), 16, 20000);
  std::vector<Eigen::Vector3d> pts;
  pts.reserve(static_cast<std::size_t>(samples));
  const double inv0 = 1.0 / o.max_depth, inv1 = 1.0 / o.min_depth;
  for (int s = 0; s < samples; ++s) {
    const Eigen::Vector3d p = along(1.0 / (inv0 + (inv1 - inv0) * s / (samples - 1)));
    if (p.z() > 1e-3) pts.push_back(p);
  }
  const std::vector<cv::Point2f> curve = calib.project(Cam::kLeft, pts);

  // Integer-pixel normalised cross-correlation along the curve.
  cv::Scalar tm, ts;
  cv::meanStdDev(templ, tm, ts);
  if (ts[0] < 1e-3) return std::nullopt;
  const cv::Mat tz = (templ - tm[0]) / ts[0];
  double best = -2.0;
  cv::Point best_p(-1, -1), last(-1000, -1000);
  for (const auto& c : curve) {
    const cv::Point q(cvRound(c.x), cvRound(c.y));
    if (q == last) continue;
    last = q;
    if (q.x < h + 1 || q.y < h + 1 || q.x > iml.cols - h - 2 || q.y > iml.rows - h - 2) continue;
    for (int dy = -1; dy <= 1; ++dy) {  // the curve is drawn at 1 px; allow the rounding
      cv::Mat patch;
      iml(cv::Rect(q.x - h, q.y - h + dy, 2 * h + 1, 2 * h + 1)).convertTo(patch, CV_32F);
      cv::Scalar m, sd;
      cv::meanStdDev(patch, m, sd);
      if (sd[0] < 1e-3) continue;
      const double ncc = tz.dot(patch - m[0]) / (sd[0] * static_cast<double>(tz.total()));
      if (ncc > best) best = ncc, best_p = {q.x, q.y + dy};
    }
  }
  if (best_p.x < 0 || best < o.min_ncc) return std::nullopt;

  // Pyramidal LK camR → camL from the correlation peak, then the corner in camL.
  // (The correlation peak is the template's centre pixel; the corner is offset from it.)
  cv::Point2f p = cv::Point2f(static_cast<float>(best_p.x), static_cast<float>(best_p.y)) + grid.offset;
  if (auto q = track_lk(right, left, p_right, p, lk); q && cv::norm(*q - p) < 3.0) p = *q;
  // The right image's patch aligned into the left one (gain and offset free): both
  // cameras then hold the same physical point, whatever a corner detector's bias.
  AlignOptions ao;
  ao.max_shift = 3.0;
  const auto refined = align_template(iml, templ, p - grid.offset, ao);
  if (!refined || refined->ncc < o.min_ncc) return std::nullopt;
  return StereoMatch{refined->position + grid.offset, refined->ncc};
}

std::optional<StereoMatch> align_on_plane(const StereoCalibration& calib, const cv::Mat& right,
                                          const cv::Mat& left, const cv::Point2f& p_right,
                                          const cv::Point2f& p_left, const Eigen::Vector3d& x,
                                          const Eigen::Vector3d& n, const StereoMatchOptions& o) {
  const auto change = plane_view_change(calib, x, n, Cam::kLeft, Cam::kRight);
  if (!change) return std::nullopt;
  const cv::Matx22d& right_of_left = *change;
  const cv::Mat templ = affine_patch(right, p_right, right_of_left, o.template_half);
  if (templ.empty()) return std::nullopt;
  AlignOptions ao;
  ao.max_shift = 1.5;
  const auto refined = align_template(left, templ, p_left, ao);
  if (!refined || refined->ncc < o.min_ncc) return std::nullopt;
  return StereoMatch{refined->position, refined->ncc};
}

}  // namespace dentmark::track
