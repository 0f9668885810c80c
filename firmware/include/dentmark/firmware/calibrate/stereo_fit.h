#pragma once
// Stereo calibration of the tracking pair from views of a planar target, with the
// figures that say how far to trust it.
//
// Procedure (one function per stage in stereo_fit.cpp):
//   1. Each camera alone: cv::calibrateCamera from the target's views (Zhang 2000),
//      giving K and D per camera — the starting point of 2.
//   2. The pair jointly: cv::stereoCalibrate with CALIB_USE_INTRINSIC_GUESS refines
//      K1 D1 K2 D2 R T together. Joint refinement rather than CALIB_FIX_INTRINSIC:
//      with R T shared by every view, each board pose is one unknown seen by both
//      cameras, so the intrinsics are fitted against twice the corners per pose; with
//      the intrinsics frozen, their errors have nowhere to go but into R T.
//   3. Outlier views: e_i is view i's stereo RMS (both cameras). The worst view is
//      rejected when e_i > max(median(e) + k · 1.4826 · MAD(e), r · median(e))
//      (k = 3, r = 2: a robust 3σ rule that never rejects inside a tight cluster);
//      1–2 are refitted without it, until no view is rejected or min_views remain.
//      One view at a time: a bad view inflates its neighbours' errors in the fit.
//   4. Hold-out: each kept view in turn is left out, 1–2 refitted on the others, and
//      the left-out view's board pose (6 numbers, both cameras) is fitted with that
//      calibration held fixed; its reprojection RMS is what the calibration predicts
//      for a view it has not seen.
//   5. Rectified epipolar error: corners mapped through cv::stereoRectify's R1 P1 /
//      R2 P2; mean |y_L − y_R| (pixels of the rectified images).
//   6. Scale check: the kept views' corners triangulated; the mean distance between
//      neighbouring corners against the square size given.

#include <limits>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "dentmark/firmware/track/stereo_calibration.h"

namespace dentmark::calibrate {

// One stereo view: the target points seen by both cameras, in the same order.
struct StereoView {
  std::string name;
  std::vector<cv::Point3f> object;  // board coordinates, metres
  std::vector<cv::Point2f> left, right;
};

enum class DistortionModel {
  kStandard,  // k1 k2 p1 p2 k3 (OpenCV's default 5 coefficients)
  kRational,  // k1 … k6, p1 p2 (CALIB_RATIONAL_MODEL, 8 coefficients)
};

struct StereoFitOptions {
  DistortionModel model = DistortionModel::kStandard;
  double outlier_mad_factor = 3.0;    // k in stage 3
  double outlier_median_ratio = 2.0;  // r in stage 3
  int min_views = 6;                  // never reject below this many views
  bool holdout = true;                // stage 4 (n refits)
};

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct ViewFigures {
  std::string name;
  bool used = false;
  std::string rejected_because;  // empty when used
  double rms_left_px = kNaN;     // this view's RMS reprojection error, final calibration
  double rms_right_px = kNaN;    // (rejected views: board pose fitted to it, calibration fixed)
  double holdout_rms_px = kNaN;  // kept views: stage 4; rejected views: with the final calibration
};

struct StereoFit {
  track::StereoCalibration calibration;  // K1 D1 K2 D2, T_camR_camL (R T), image size
  int views_used = 0;
  double rms_px = kNaN;  // cv::stereoCalibrate's RMS over the kept views
  double rms_left_px = kNaN, rms_right_px = kNaN;
  double epipolar_rectified_px = kNaN;  // stage 5, mean |y_L − y_R|
  double epipolar_rectified_max_px = kNaN;
  double holdout_rms_px = kNaN;       // stage 4, RMS over all held-out views' corners
  double holdout_max_view_px = kNaN;  // the worst held-out view
  double square_given_m = kNaN;
  double square_measured_m = kNaN;  // stage 6
  std::vector<ViewFigures> views;   // every view passed in, in order
};

// Calibrates from views whose corners were found in both images. 'square_m' is the
// target's square (for stage 6). Throws CalibrateError when fewer than
// options.min_views views are given or OpenCV fails to fit.
StereoFit fit_stereo(const std::vector<StereoView>& views, cv::Size image_size, double square_m,
                     const StereoFitOptions& options = {});

// The RMS reprojection error (pixels) of one view in each camera after fitting its
// board pose to both images with the calibration held fixed. Used for held-out and
// rejected views.
struct ViewPrediction {
  double rms_left_px = kNaN, rms_right_px = kNaN;
  double rms_px() const;  // over both cameras' corners
};
ViewPrediction predict_view(const track::StereoCalibration& calibration, const StereoView& view);

}  // namespace dentmark::calibrate
