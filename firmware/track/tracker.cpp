#include "dentmark/firmware/track/tracker.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "dentmark/common/geometry/rigid_fit.h"
#include "dentmark/common/nth_smallest.h"
#include "dentmark/firmware/track/plane_view.h"
#include "dentmark/firmware/track/pose_refine.h"
#include "dentmark/firmware/track/template_align.h"
#include "dentmark/firmware/track/track_error.h"

namespace dentmark::track {
namespace {

cv::Mat as_grey(const cv::Mat& img) {
  if (img.channels() == 1) return img;
  cv::Mat g;
  cv::cvtColor(img, g, img.channels() == 4 ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGR2GRAY);
  return g;
}

void check_size(const cv::Mat& img, const cv::Size& size, const char* which) {
  if (img.empty() || img.size() != size || img.depth() != CV_8U)
    throw TrackError(std::string("tracker: ") + which + " image is not an 8-bit " +
                     std::to_string(size.width) + "x" + std::to_string(size.height) + " image");
}

// Searches the template near `around` and refines the corner there.
std::optional<cv::Point2f> find_near(const cv::Mat& grey, const GridTemplate& grid, const cv::Point2f& around,
                                     int radius, double min_ncc) {
  const cv::Mat& templ = grid.patch;
  const int h = templ.cols / 2;
  const cv::Rect area = cv::Rect(cvRound(around.x) - radius - h, cvRound(around.y) - radius - h,
                                 2 * (radius + h) + 1, 2 * (radius + h) + 1);
  if ((area & cv::Rect(0, 0, grey.cols, grey.rows)) != area) return std::nullopt;
  cv::Mat region, score;
  grey(area).convertTo(region, CV_32F);
  cv::matchTemplate(region, templ, score, cv::TM_CCOEFF_NORMED);
  double best;
  cv::Point loc;
  cv::minMaxLoc(score, nullptr, &best, nullptr, &loc);
  if (!(best >= min_ncc)) return std::nullopt;
  const cv::Point2f start(static_cast<float>(area.x + loc.x + h), static_cast<float>(area.y + loc.y + h));
  const auto c = align_template(grey, templ, start);
  if (!c || c->ncc < min_ncc || cv::norm(c->position + grid.offset - around) > radius + 1.0)
    return std::nullopt;
  return c->position + grid.offset;
}

// --- The stages of Tracker::start ---

// A seed that became a stereo feature of the first frame: its corner in each image and
// its position in camL (m).
struct SeedFeature {
  int seed;  // index into the seeds
  cv::Point2f l, r;
  Eigen::Vector3d p;
};

// Each seed refined to a corner in camR, matched into camL and triangulated; kept when it
// reprojects within max_reprojection and lies in front of the cameras. Two seeds that
// snapped onto one corner give one feature.
std::vector<SeedFeature> match_seeds(const StereoCalibration& calib, const TrackerOptions& opt,
                                     const cv::Mat& right, const ImagePyramid& pl, const ImagePyramid& pr,
                                     std::span<const cv::Point2f> seeds_right) {
  std::vector<SeedFeature> found;
  for (std::size_t k = 0; k < seeds_right.size(); ++k) {
    const auto cr = refine_seed(right, seeds_right[k], opt.corner);
    if (!cr) continue;
    const auto m = match_right_to_left(calib, pr, pl, *cr, opt.stereo, opt.lk);
    if (!m) continue;
    const Triangulation tri =
        triangulate(calib, calib.normalize(Cam::kLeft, {m->left})[0], calib.normalize(Cam::kRight, {*cr})[0]);
    if (tri.reprojection_px > opt.max_reprojection || !(tri.p_camL.z() > 0)) continue;
    const bool duplicate = std::any_of(found.begin(), found.end(),
                                       [&](const SeedFeature& c) { return cv::norm(c.r - *cr) < 2.0; });
    if (!duplicate) found.push_back({static_cast<int>(k), m->left, *cr, tri.p_camL});
  }
  return found;
}

// Features on one panel lie at similar depths; one under half or over twice the median
// depth matched the wrong corner and is dropped.
void drop_depth_outliers(std::vector<SeedFeature>& found) {
  if (found.empty()) return;
  std::vector<double> z;
  for (const auto& c : found) z.push_back(c.p.z());
  const double med = median_in_place(z);
  std::erase_if(found, [&](const SeedFeature& c) { return c.p.z() < 0.5 * med || c.p.z() > 2.0 * med; });
}

// The camL positions again (two passes), with the camR patch seen as camL sees the
// panel's plane (stereo_match.h: translation alone leaves 0.1-0.5 px of disparity error,
// which the reference would keep for the whole run and which grows into motion error as
// the viewing geometry changes with travel). A feature whose aligned match fails keeps
// its previous corner and position.
void align_on_panel_plane(const StereoCalibration& calib, const TrackerOptions& opt, const cv::Mat& left,
                          const cv::Mat& right, std::vector<SeedFeature>& found) {
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<Eigen::Vector3d> points;
    for (const auto& f : found) points.push_back(f.p);
    const auto normal = plane_normal(points);
    if (!normal) break;
    for (auto& f : found) {
      const auto m = align_on_plane(calib, right, left, f.r, f.l, f.p, *normal, opt.stereo);
      if (!m) continue;
      const Triangulation tri = triangulate(calib, calib.normalize(Cam::kLeft, {m->left})[0],
                                            calib.normalize(Cam::kRight, {f.r})[0]);
      if (tri.reprojection_px > opt.max_reprojection || !(tri.p_camL.z() > 0)) continue;
      f.l = m->left;
      f.p = tri.p_camL;
    }
  }
}

}  // namespace

double Tracker::expected_depth_error(double depth) const {
  const double f = 0.5 * (calib_.left.K(0, 0) + calib_.right.K(0, 0));
  const double baseline = calib_.T_camR_camL.translation().norm();
  return depth * depth / (f * baseline) * opt_.disparity_noise;
}

double Tracker::disagreement_limit() const {
  return std::max(opt_.max_disagreement, 8.0 * expected_depth_error(reference_depth_));
}

GridTemplate Tracker::template_now(std::size_t i, Cam cam, const Transform& motion) const {
  const GridTemplate& grid = cam == Cam::kLeft ? reference_[i].template_left : reference_[i].template_right;
  if (plane_normal_.isZero()) return grid;
  // The local affine map of this camera's pixel offsets from the first frame to now,
  // for the panel's plane at the feature: the panel turns and crosses the view as it
  // travels (up to ~10 degrees over a run), and a template matched by translation
  // alone drifts off the corner by a fraction of the neighbouring structure's apparent
  // shift, differently in the two cameras: depth error that grows with travel.
  const auto change = plane_view_change(calib_, reference_[i].p_camL, plane_normal_, cam, cam, motion);
  if (!change) return grid;
  const cv::Matx22d& now_of_first = *change;
  const cv::Matx22d d = now_of_first - cv::Matx22d::eye();
  // Below ~0.01 px across the patch the grid template itself is exact.
  if (std::max({std::abs(d(0, 0)), std::abs(d(0, 1)), std::abs(d(1, 0)), std::abs(d(1, 1))}) < 1e-3)
    return grid;
  // Re-cut about the same grid centre, so the feature keeps its offset (mapped).
  const cv::Point2f& first_px = cam == Cam::kLeft ? first_left_px_[i] : first_right_px_[i];
  const cv::Point2d centre(first_px.x - grid.offset.x, first_px.y - grid.offset.y);
  GridTemplate warped;
  warped.patch = affine_patch(cam == Cam::kLeft ? first_left_ : first_right_, centre, now_of_first.inv(),
                              grid.patch.cols / 2);
  if (warped.patch.empty()) return grid;
  const cv::Vec2d o = now_of_first * cv::Vec2d(grid.offset.x, grid.offset.y);
  warped.offset = cv::Point2f(static_cast<float>(o[0]), static_cast<float>(o[1]));
  return warped;
}

Tracker::Tracker(StereoCalibration calibration, TrackerOptions options)
    : calib_(std::move(calibration)),
      opt_(options),
      filter_(Eigen::Vector3d::Zero(), options.filter),
      line_(options.line) {}

FrameResult Tracker::start(const cv::Mat& left_in, const cv::Mat& right_in, double t,
                           std::span<const cv::Point2f> seeds_right, long index) {
  const cv::Mat left = as_grey(left_in), right = as_grey(right_in);
  check_size(left, calib_.size, "left");
  check_size(right, calib_.size, "right");
  const ImagePyramid pl(left, opt_.lk), pr(right, opt_.lk);

  std::vector<SeedFeature> found = match_seeds(calib_, opt_, right, pl, pr, seeds_right);
  drop_depth_outliers(found);
  align_on_panel_plane(calib_, opt_, left, right, found);
  if (static_cast<int>(found.size()) < opt_.min_features)
    throw TrackError("only " + std::to_string(found.size()) + " of " + std::to_string(seeds_right.size()) +
                     " seeds gave usable stereo features (need " + std::to_string(opt_.min_features) + ")");

  // The reference: each feature's camL position and its templates in both first images.
  reference_ = ReferenceBuffer();
  seed_of_feature_.clear();
  left_.clear();
  right_.clear();
  for (const auto& c : found) {
    ReferenceFeature f;
    f.p_camL = c.p;
    f.template_left = grid_template(left, c.l, opt_.template_half);
    f.template_right = grid_template(right, c.r, opt_.template_half);
    if (f.template_left.patch.empty() || f.template_right.patch.empty()) continue;
    reference_.add(f);
    seed_of_feature_.push_back(c.seed);
    left_.push_back(c.l);
    right_.push_back(c.r);
  }
  if (static_cast<int>(reference_.size()) < opt_.min_features)
    throw TrackError("only " + std::to_string(reference_.size()) +
                     " features lie far enough inside the images");
  begin_run(left, right, pl, pr, t);

  FrameResult r;
  r.index = index;
  r.t = t;
  r.ok = true;
  r.features = static_cast<int>(reference_.size());
  r.quality =
      static_cast<double>(found.size()) / static_cast<double>(std::max<std::size_t>(seeds_right.size(), 1));
  return r;
}

void Tracker::begin_run(const cv::Mat& left, const cv::Mat& right, const ImagePyramid& pl,
                        const ImagePyramid& pr, double t) {
  active_.assign(reference_.size(), true);
  first_left_ = left;
  first_right_ = right;
  first_left_px_ = left_;
  first_right_px_ = right_;
  first_left_n_ = calib_.normalize(Cam::kLeft, left_);
  first_right_n_ = calib_.normalize(Cam::kRight, right_);
  const std::vector<Eigen::Vector3d> layout = reference_.points();
  plane_normal_ = plane_normal(layout).value_or(Eigen::Vector3d::Zero());
  filter_centre_ = reference_.centroid();
  filter_ = MotionFilter(filter_centre_, opt_.filter);
  line_ = ConveyorLine(opt_.line);
  conveyor_ = false;
  spread_ = [&] {
    double s = 0.0;
    for (const auto& p : layout) s += (p - filter_centre_).squaredNorm();
    return std::sqrt(s / static_cast<double>(layout.size()));
  }();
  px_rms_ema_ = 0.0;
  filter_.reset(t);
  reference_depth_ = reference_.centroid().z();
  prev_left_ = pl;
  prev_right_ = pr;
  rms_ema_ = 0.0;
  started_ = true;
}

bool Tracker::reacquire(std::size_t i, const Transform& motion, const ImagePyramid& left,
                        const ImagePyramid& right, Eigen::Vector3d& p) {
  const Eigen::Vector3d x = motion * reference_[i].p_camL;
  const cv::Point2f gl = calib_.project(Cam::kLeft, {x})[0], gr = calib_.project(Cam::kRight, {x})[0];
  // Through the view change since the first frame: a corner that re-enters the view (or
  // comes out from behind the arm) far down the line no longer looks like its grid template.
  const auto l = find_near(left.image(), template_now(i, Cam::kLeft, motion), gl, opt_.reacquire_radius,
                           opt_.reacquire_ncc);
  if (!l) return false;
  const auto r = find_near(right.image(), template_now(i, Cam::kRight, motion), gr, opt_.reacquire_radius,
                           opt_.reacquire_ncc);
  if (!r) return false;
  const Triangulation tri =
      triangulate(calib_, calib_.normalize(Cam::kLeft, {*l})[0], calib_.normalize(Cam::kRight, {*r})[0]);
  if (tri.reprojection_px > opt_.max_reprojection || (tri.p_camL - x).norm() > opt_.max_disagreement)
    return false;
  p = tri.p_camL;
  left_[i] = *l;
  right_[i] = *r;
  return true;
}

FrameResult Tracker::skip(double t, long index, const std::string& why) {
  FrameResult r;
  r.index = index;
  r.t = t;
  r.ok = false;
  r.motion = started_ ? filter_.predict(t) : Transform::Identity();
  r.raw_motion = r.motion;
  r.note = why;
  return r;
}

namespace {

// The part of an image where features can be found this frame: LK's reach around their
// last (a) and predicted (b) positions; a tenth to a third of a 1280 x 1024 frame.
cv::Rect search_region(const LkOptions& lk, const std::vector<cv::Point2f>& a,
                       const std::vector<cv::Point2f>& b) {
  const int reach = lk.window * (1 << lk.levels) / 2 + 2 * lk.window + 16;
  float x0 = 1e9f, y0 = 1e9f, x1 = -1e9f, y1 = -1e9f;
  for (const auto* v : {&a, &b})
    for (const auto& p : *v)
      if (std::isfinite(p.x) && std::isfinite(p.y))
        x0 = std::min(x0, p.x), y0 = std::min(y0, p.y), x1 = std::max(x1, p.x), y1 = std::max(y1, p.y);
  if (x1 < x0) return cv::Rect();
  return cv::Rect(cv::Point(static_cast<int>(x0) - reach, static_cast<int>(y0) - reach),
                  cv::Point(static_cast<int>(x1) + reach + 1, static_cast<int>(y1) + reach + 1));
}

}  // namespace

std::optional<cv::Point2f> Tracker::follow(const ImagePyramid& prev, const ImagePyramid& cur,
                                           const cv::Point2f& from, const cv::Point2f& guess,
                                           const GridTemplate& templ) const {
  const auto fwd = track_lk(prev, cur, from, guess, opt_.lk);
  if (!fwd) return std::nullopt;
  const auto back = track_lk(cur, prev, *fwd, from, opt_.lk);
  if (!back || cv::norm(*back - from) > opt_.max_fb_error) return std::nullopt;
  // Refine against the first frame's template: drift-free and lighting-proof.
  AlignOptions ao;
  ao.max_shift = opt_.max_subpix_shift;
  const auto c = align_template(cur.image(), templ.patch, *fwd - templ.offset, ao);
  if (!c || c->ncc < opt_.min_appearance_ncc) return std::nullopt;
  return c->position + templ.offset;
}

void Tracker::follow_features(const ImagePyramid& pl, const ImagePyramid& pr,
                              const std::vector<cv::Point2f>& gl, const std::vector<cv::Point2f>& gr,
                              const Transform& predicted, std::vector<Eigen::Vector3d>& current,
                              std::vector<bool>& valid) {
  for (std::size_t i = 0; i < current.size(); ++i) {
    if (!active_[i]) continue;
    const auto l = follow(prev_left_, pl, left_[i], gl[i], template_now(i, Cam::kLeft, predicted));
    const auto r =
        l ? follow(prev_right_, pr, right_[i], gr[i], template_now(i, Cam::kRight, predicted)) : std::nullopt;
    if (!l || !r) continue;
    const Triangulation tri =
        triangulate(calib_, calib_.normalize(Cam::kLeft, {*l})[0], calib_.normalize(Cam::kRight, {*r})[0]);
    if (tri.reprojection_px > opt_.max_reprojection) continue;
    current[i] = tri.p_camL;
    valid[i] = true;
    left_[i] = *l;
    right_[i] = *r;
  }
  // Geometric check against the reference layout (rigid: distances are kept).
  const std::vector<double> dis = reference_.distance_disagreement(current, valid);
  for (std::size_t i = 0; i < current.size(); ++i)
    if (valid[i] && dis[i] > disagreement_limit()) valid[i] = false;
}

bool Tracker::reacquire_lost(const Transform& motion, const ImagePyramid& pl, const ImagePyramid& pr,
                             std::vector<Eigen::Vector3d>& current, std::vector<bool>& valid) {
  bool any = false;
  for (std::size_t i = 0; i < current.size(); ++i)
    if (!valid[i] && reacquire(i, motion, pl, pr, current[i])) valid[i] = any = true;
  return any;
}

void Tracker::accept(FrameResult& result, double t, const std::vector<Eigen::Vector3d>& current,
                     const std::vector<bool>& valid) {
  const std::size_t n = current.size();
  // Only frames that see most of the panel refine the layout: their motion is well
  // determined, so mapping their features back adds little error of its own.
  if (result.features >= opt_.refine_min_share * static_cast<double>(n))
    refine_reference(current, valid, result.raw_motion);
  rms_ema_ = rms_ema_ > 0.0 ? 0.9 * rms_ema_ + 0.1 * result.rms : result.rms;
  px_rms_ema_ = px_rms_ema_ > 0.0 ? 0.9 * px_rms_ema_ + 0.1 * px_rms_now_ : px_rms_now_;
  // The fit's covariance from its image residuals (pose_refine.h), in the filter's
  // coordinates (rotation about the reference centroid, translation of the centroid):
  // each coordinate gets its own uncertainty, and depth and the tilt it drives are
  // trusted as little as the disparity allows, not as much as the lateral position.
  const Eigen::Matrix<double, 6, 1> sd = fit_deviation(result.raw_motion);
  const Transform filtered = filter_.update(t, result.raw_motion, sd.head<3>(), sd.tail<3>());
  // The conveyor's line (conveyor_line.h): across it is noise, and the panel does not
  // turn on it. A filtered rotation within the gate of one frame's rotation noise is the
  // first frame's tilt error that every M(k) inherits (a fit of a wide, short layout
  // tilts by its depth noise; at the lower door it is 1-2 mm), not motion.
  line_.add(filter_.to_params(result.raw_motion).tail<3>());
  Eigen::Matrix<double, 6, 1> p = filter_.to_params(filtered);
  const bool turning = (p.head<3>().cwiseAbs().array() > opt_.line.turn_gate * sd.head<3>().array()).any();
  conveyor_ = opt_.line.enabled && !turning;
  if (conveyor_) {
    p.tail<3>() = line_.onto_line(p.tail<3>());  // unchanged until the direction is known
    p.head<3>().setZero();
  }
  result.motion = filter_.from_params(p);
  result.expected_error = expected_error(sd);
}

Eigen::Matrix<double, 6, 1> Tracker::fit_deviation(const Transform& motion) const {
  // (δω, δτ) → (δω, δt): δt = δτ + [M c]× δω, with c the filter's centre.
  const Eigen::Vector3d q = motion * filter_centre_;
  Eigen::Matrix<double, 6, 6> b = Eigen::Matrix<double, 6, 6>::Identity();
  b.block<3, 3>(3, 0) << 0, -q.z(), q.y(), q.z(), 0, -q.x(), -q.y(), q.x(), 0;
  const Eigen::Matrix<double, 6, 6> info = b.transpose() * last_information_ * b;
  // Pixel noise: the refinement's residual RMS (over 4n residuals, 6 parameters), never
  // below the matching noise the options assume.
  const double px = std::max(opt_.disparity_noise, px_rms_ema_);
  const Eigen::Matrix<double, 6, 6> cov =
      px * px * info.ldlt().solve(Eigen::Matrix<double, 6, 6>::Identity());
  Eigen::Matrix<double, 6, 1> sd;
  for (int i = 0; i < 6; ++i) sd(i) = std::sqrt(std::max(cov(i, i), 1e-18));
  if (!sd.allFinite()) sd.setConstant(1.0);
  return sd;
}

double Tracker::expected_error(const Eigen::Matrix<double, 6, 1>& fit_sd) const {
  // RMS error at the reference features: translation of the centroid plus rotation
  // times the features' spread about it (2/3 of it perpendicular to a random axis).
  const Eigen::Matrix<double, 6, 1> v = filter_.variance();
  const double k = (2.0 / 3.0) * spread_ * spread_;
  if (conveyor_) {
    // On the line: the filtered translation along it, and how well the filter knows
    // the rotation to be none.
    const auto d = line_.direction();
    const double along = d ? d->cwiseAbs2().dot(v.tail<3>()) : v.tail<3>().sum();
    return std::sqrt(along + v.head<3>().sum() * k);
  }
  // Off it: the filter's posterior, plus the first frame's own tilt error (about one
  // frame's rotation deviation), which every M(k) inherits and no filter sees.
  return std::sqrt(v.tail<3>().sum() + (v.head<3>().sum() + fit_sd.head<3>().squaredNorm()) * k);
}

FrameResult Tracker::track(const cv::Mat& left_in, const cv::Mat& right_in, double t, long index) {
  if (!started_) throw TrackError("tracker: track() before start()");
  const cv::Mat left = as_grey(left_in), right = as_grey(right_in);
  check_size(left, calib_.size, "left");
  check_size(right, calib_.size, "right");
  const std::size_t n = reference_.size();

  // Constant-velocity prediction: where each feature should be now, in both cameras.
  const Transform predicted = filter_.predict(t);
  std::vector<Eigen::Vector3d> xp(n);
  const std::vector<Eigen::Vector3d> ref = reference_.points();
  for (std::size_t i = 0; i < n; ++i) xp[i] = predicted * ref[i];
  const std::vector<cv::Point2f> gl = calib_.project(Cam::kLeft, xp), gr = calib_.project(Cam::kRight, xp);
  const ImagePyramid pl(left, opt_.lk, search_region(opt_.lk, gl, left_));
  const ImagePyramid pr(right, opt_.lk, search_region(opt_.lk, gr, right_));

  std::vector<Eigen::Vector3d> current(n, Eigen::Vector3d::Zero());
  std::vector<bool> valid(n, false);
  follow_features(pl, pr, gl, gr, predicted, current, valid);
  FrameResult result = fit_and_filter(index, t, current, valid);
  // Everything lost (e.g. a full occlusion): look again where the prediction says.
  if (!result.ok && reacquire_lost(predicted, pl, pr, current, valid))
    result = fit_and_filter(index, t, current, valid);
  // Re-acquire lost features near their positions under this frame's motion.
  if (result.ok && reacquire_lost(result.raw_motion, pl, pr, current, valid))
    result = fit_and_filter(index, t, current, valid);
  active_ = valid;
  if (result.ok) {
    accept(result, t, current, valid);  // filter state only from accepted fits
  } else {
    result.motion = predicted;
    result.raw_motion = predicted;
  }
  prev_left_ = pl;
  prev_right_ = pr;
  return result;
}

void Tracker::refine_reference(const std::vector<Eigen::Vector3d>& current, const std::vector<bool>& valid,
                               const Transform& motion) {
  reference_.add_observation(motion, current, valid);
  const std::vector<Eigen::Vector3d> mean = reference_.averaged();
  // Back onto the first frame: the placement whose reprojection best matches the first
  // frame's features (the same image residuals that give every M(k)), so M(0) = I.
  try {
    const Transform start = fit_rigid(mean, reference_.points()).T_to_from;
    const Transform anchor = refine_pose(calib_, start, mean, first_left_n_, first_right_n_).motion;
    std::vector<Eigen::Vector3d> placed(mean.size());
    for (std::size_t i = 0; i < mean.size(); ++i) placed[i] = anchor * mean[i];
    reference_.set_points(placed);
  } catch (const GeometryError&) {
  }
}

FrameResult Tracker::fit_and_filter(long index, double t, std::vector<Eigen::Vector3d>& current,
                                    std::vector<bool>& valid) {
  FrameResult r;
  r.index = index;
  r.t = t;
  std::vector<Eigen::Vector3d> from, to;
  std::vector<double> w;
  std::vector<std::size_t> ids;
  std::vector<double> z;
  for (std::size_t i = 0; i < valid.size(); ++i)
    if (valid[i]) z.push_back(current[i].z());
  if (static_cast<int>(z.size()) < opt_.min_features) {
    r.note = "only " + std::to_string(z.size()) + " features tracked";
    return r;
  }
  const double zmed = median_in_place(z);
  for (std::size_t i = 0; i < valid.size(); ++i) {
    if (!valid[i]) continue;
    from.push_back(reference_[i].p_camL);
    to.push_back(current[i]);
    // Triangulation error grows with depth squared; weight = 1 / variance.
    w.push_back(std::pow(zmed / current[i].z(), 4));
    ids.push_back(i);
  }
  try {
    // The residual scale never assumed below what triangulation can give here: depth
    // error Z² / (f B) per pixel of disparity error.
    RobustMotionOptions ro = opt_.robust;
    ro.noise_floor = std::max(ro.noise_floor, expected_depth_error(zmed));
    const RobustMotion fit = fit_rigid_robust(from, to, w, ro);
    if (fit.inliers < opt_.min_features) throw GeometryError("too few inliers");
    for (std::size_t k = 0; k < ids.size(); ++k)
      if (!fit.inlier[k]) valid[ids[k]] = false;
    r.ok = true;
    r.features = fit.inliers;
    // Polish on the image residuals of the inliers (pose_refine.h).
    std::vector<Eigen::Vector3d> ref_in;
    std::vector<cv::Point2f> pl, pr;
    for (std::size_t k = 0; k < ids.size(); ++k)
      if (fit.inlier[k]) {
        ref_in.push_back(reference_[ids[k]].p_camL);
        pl.push_back(left_[ids[k]]);
        pr.push_back(right_[ids[k]]);
      }
    const PoseRefineResult refined = refine_pose(
        calib_, fit.T_to_from, ref_in, calib_.normalize(Cam::kLeft, pl), calib_.normalize(Cam::kRight, pr));
    r.raw_motion = refined.motion;
    r.motion = refined.motion;
    last_information_ = refined.information;
    const double dof = std::max(1.0, 4.0 * static_cast<double>(ref_in.size()) - 6.0);
    const double px_rms = refined.rms_px * std::sqrt(4.0 * static_cast<double>(ref_in.size()) / dof);
    px_rms_now_ = px_rms;
    r.rms = fit.rms;
    const double share = static_cast<double>(fit.inliers) / static_cast<double>(reference_.size());
    r.quality = share / (1.0 + std::pow(fit.rms / 1e-3, 2));
  } catch (const GeometryError& e) {
    r.note = e.what();
  }
  return r;
}

}  // namespace dentmark::track
