#pragma once
// The edge's pose-and-motion tracker of the moving panel (paper §IV-A, design.md §4).
//
// start(): seeds → Shi-Tomasi + cornerSubPix in camR → camR→camL match → sub-pixel in
// camL → triangulation → reference buffer.
// track(): per frame, one pyramid per image; LK from the previous frame in both cameras
// from the constant-velocity prediction; forward–backward check; sub-pixel refinement;
// appearance check against the reference templates; triangulation; pairwise-distance
// check against the reference buffer; robust weighted rigid fit of the reference onto
// the current features; re-acquisition of lost features near their predicted
// positions; then the motion filter. M(k) maps camL at the first frame to camL at k.

#include <opencv2/core.hpp>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "dentmark/firmware/track/conveyor_line.h"
#include "dentmark/firmware/track/corner_refine.h"
#include "dentmark/firmware/track/motion_filter.h"
#include "dentmark/firmware/track/pyramid_lk.h"
#include "dentmark/firmware/track/reference_buffer.h"
#include "dentmark/firmware/track/robust_motion.h"
#include "dentmark/firmware/track/stereo_calibration.h"
#include "dentmark/firmware/track/stereo_match.h"
#include "dentmark/firmware/track/template_align.h"

namespace dentmark::track {

struct TrackerOptions {
  CornerOptions corner;
  LkOptions lk;
  StereoMatchOptions stereo;
  RobustMotionOptions robust;
  MotionFilterOptions filter;
  ConveyorLineOptions line;
  int template_half = 7;          // appearance / re-acquisition template, px
  double max_fb_error = 0.5;      // forward–backward LK disagreement, px
  double max_subpix_shift = 2.0;  // cornerSubPix may move an LK point this far, px
  double min_appearance_ncc = 0.75;
  double reacquire_ncc = 0.8;
  int reacquire_radius = 6;         // px around the prediction
  double max_reprojection = 1.0;    // px, triangulation
  double max_disagreement = 0.004;  // m, pairwise distances vs the reference
  double disparity_noise = 0.05;    // px: expected matching noise; scales the depth tolerances
  int min_features = 3;
  // The reference layout is refined from frames whose fit uses at least this share of
  // the reference features (reference_buffer.h); above 1 turns the refinement off.
  double refine_min_share = 0.7;
};

struct FrameResult {
  long index = 0;
  double t = 0.0;
  bool ok = false;
  int features = 0;                              // features used in the fit
  Transform motion = Transform::Identity();      // filtered M(k) (the prediction if !ok)
  Transform raw_motion = Transform::Identity();  // this frame's fit alone
  double rms = 0.0;                              // fit residual RMS, m
  double quality = 0.0;                          // 0..1: inlier share × residual term
  double expected_error = 0.0;                   // m: the motion's expected error at the panel
  std::string note;                              // why !ok
};

class Tracker {
 public:
  Tracker(StereoCalibration calibration, TrackerOptions options = {});

  // Builds the reference buffer from the first stereo frame and rough camR seeds.
  // Throws TrackError when fewer than min_features seeds give usable stereo features.
  FrameResult start(const cv::Mat& left, const cv::Mat& right, double t,
                    std::span<const cv::Point2f> seeds_right, long index = 0);
  // Tracks one more stereo frame (t strictly increasing).
  FrameResult track(const cv::Mat& left, const cv::Mat& right, double t, long index);
  // A frame that could not be read: predict through it.
  FrameResult skip(double t, long index, const std::string& why);

  const ReferenceBuffer& reference() const { return reference_; }
  // Which seeds became reference features (index into the seeds of start()).
  const std::vector<int>& seed_of_feature() const { return seed_of_feature_; }
  // Current pixel positions of the features (left, right) and whether each is tracked.
  const std::vector<cv::Point2f>& left_points() const { return left_; }
  const std::vector<cv::Point2f>& right_points() const { return right_; }
  const std::vector<bool>& tracked() const { return active_; }

 private:
  // A feature from the previous pyramid to the current one: LK forward and back, then
  // aligned to its first-frame template 'templ'; nullopt when any check fails.
  std::optional<cv::Point2f> follow(const ImagePyramid& prev, const ImagePyramid& cur,
                                    const cv::Point2f& from, const cv::Point2f& guess,
                                    const GridTemplate& templ) const;
  // Follows every active feature in both cameras (predicted at gl, gr), triangulates it
  // and drops those that break the reference layout's distances.
  void follow_features(const ImagePyramid& pl, const ImagePyramid& pr, const std::vector<cv::Point2f>& gl,
                       const std::vector<cv::Point2f>& gr, const Transform& predicted,
                       std::vector<Eigen::Vector3d>& current, std::vector<bool>& valid);
  // Looks for each lost feature near where 'motion' puts it; true if any came back.
  bool reacquire_lost(const Transform& motion, const ImagePyramid& pl, const ImagePyramid& pr,
                      std::vector<Eigen::Vector3d>& current, std::vector<bool>& valid);
  // An accepted fit: refines the reference layout and updates the motion filter.
  void accept(FrameResult& result, double t, const std::vector<Eigen::Vector3d>& current,
              const std::vector<bool>& valid);
  FrameResult fit_and_filter(long index, double t, std::vector<Eigen::Vector3d>& current,
                             std::vector<bool>& valid);
  // start()'s last stage, the reference taken: the first frame kept for re-cutting
  // templates, the filter, line and quality figures reset, (pl, pr) the previous frame.
  void begin_run(const cv::Mat& left, const cv::Mat& right, const ImagePyramid& pl, const ImagePyramid& pr,
                 double t);
  bool reacquire(std::size_t i, const Transform& motion, const ImagePyramid& left, const ImagePyramid& right,
                 Eigen::Vector3d& p_camL);

  // Averages this frame's features into the reference layout (reference_buffer.h).
  void refine_reference(const std::vector<Eigen::Vector3d>& current, const std::vector<bool>& valid,
                        const Transform& motion);
  // Feature i's reference template in camera c as it should look under `motion`.
  GridTemplate template_now(std::size_t i, Cam c, const Transform& motion) const;

  double expected_depth_error(double depth) const;
  // Standard deviations of the last fit in the filter's six coordinates.
  Eigen::Matrix<double, 6, 1> fit_deviation(const Transform& motion) const;
  // The reported motion's expected RMS error at the reference features, m (fit_sd:
  // this frame's fit_deviation).
  double expected_error(const Eigen::Matrix<double, 6, 1>& fit_sd) const;
  double disagreement_limit() const;

  StereoCalibration calib_;
  TrackerOptions opt_;
  ReferenceBuffer reference_;
  std::vector<int> seed_of_feature_;
  MotionFilter filter_;
  ConveyorLine line_;
  bool conveyor_ = false;  // the last motion was reported on the conveyor's line
  ImagePyramid prev_left_, prev_right_;
  std::vector<cv::Point2f> left_, right_;
  std::vector<bool> active_;
  // The first frame (shared, not copied), where the features were in it, and the
  // normal of the plane through the reference layout (zero: no plane): the reference
  // templates are re-cut through the predicted change of view (template_now).
  cv::Mat first_left_, first_right_;
  std::vector<cv::Point2f> first_left_px_, first_right_px_;
  std::vector<cv::Point2d> first_left_n_, first_right_n_;  // undistorted, normalised
  Eigen::Vector3d plane_normal_ = Eigen::Vector3d::Zero();
  double rms_ema_ = 0.0;
  double px_rms_ema_ = 0.0, px_rms_now_ = 0.0;  // pose refinement's residual, px
  Eigen::Matrix<double, 6, 6> last_information_ = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Vector3d filter_centre_ = Eigen::Vector3d::Zero();
  double spread_ = 0.0;  // RMS distance of the reference features from their centroid, m
  double reference_depth_ = 1.0;
  bool started_ = false;
};

}  // namespace dentmark::track
