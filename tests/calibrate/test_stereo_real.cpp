// Stereo calibration on real images: the 13 opencv-doc pairs, against OpenCV's own
// stereo_calib sample procedure run in the same process on the same files.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgcodecs.hpp>

#include "../support/temp_dir.h"
#include "dentmark/firmware/calibrate/stereo_from_images.h"
#include "opencv_sample_data.h"

namespace dentmark::calibrate {
namespace {

namespace fs = std::filesystem;
using test::kOpenCvData;

TargetSpec board_9x6() {
  return parse_target("chessboard:9x6", 0.025, 0.0, "");
}

// Our corners and fit on the given pairs, with the outlier rule switched off.
StereoFit fit_all_views(const std::vector<ImagePair>& pairs) {
  const TargetSpec t = board_9x6();
  std::vector<StereoView> views;
  cv::Size size;
  for (const ImagePair& p : pairs) {
    const cv::Mat l = cv::imread(p.left.string(), cv::IMREAD_GRAYSCALE);
    const cv::Mat r = cv::imread(p.right.string(), cv::IMREAD_GRAYSCALE);
    size = l.size();
    const Detection dl = detect_target(t, l), dr = detect_target(t, r);
    if (dl.found && dr.found) views.push_back(stereo_view(t, p.name, dl, dr));
  }
  StereoFitOptions o;
  o.outlier_mad_factor = o.outlier_median_ratio = 1e9;
  o.holdout = false;
  return fit_stereo(views, size, t.square_m, o);
}

class RealPairs : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string problem = test::opencv_data_problem();
    if (!problem.empty()) FAIL() << problem;
    test::copy_opencv_pairs(dir_.path());
  }
  ::dentmark::test::TempDir dir_{"calib-real"};
};

TEST_F(RealPairs, NoWorseThanOpenCvStereoCalibSample) {
  const std::vector<ImagePair> pairs = find_image_pairs(dir_.path());
  ASSERT_EQ(pairs.size(), 13u);
  std::vector<fs::path> lefts, rights;
  for (const ImagePair& p : pairs) lefts.push_back(p.left), rights.push_back(p.right);

  const test::SampleResult sample = test::opencv_sample_stereo_calib(lefts, rights, 0.025);
  const StereoFit all = fit_all_views(pairs);
  const StereoCalibrationRun ours = calibrate_stereo_images(dir_.path(), board_9x6());
  const StereoFit& f = ours.fit;

  std::printf("OpenCV stereo_calib sample: %d pairs, RMS %.4f px\n", sample.pairs, sample.rms_px);
  std::printf("ours, same %d views, no rejection: RMS %.4f px\n", all.views_used, all.rms_px);
  std::printf(
      "ours, command's procedure: %d views kept, RMS %.4f px, epipolar %.4f px (max %.3f), hold-out %.4f px "
      "(worst %.3f), square %.6f m\n",
      f.views_used, f.rms_px, f.epipolar_rectified_px, f.epipolar_rectified_max_px, f.holdout_rms_px,
      f.holdout_max_view_px, f.square_measured_m);
  for (const ViewFigures& v : ours.views)
    std::printf("  view %s used %d left %.3f right %.3f hold-out %.3f %s\n", v.name.c_str(), v.used,
                v.rms_left_px, v.rms_right_px, v.holdout_rms_px, v.rejected_because.c_str());
  RecordProperty("sample_rms_px", std::to_string(sample.rms_px));
  RecordProperty("ours_all_views_rms_px", std::to_string(all.rms_px));
  RecordProperty("ours_rms_px", std::to_string(f.rms_px));

  ASSERT_EQ(sample.pairs, 13);
  ASSERT_EQ(all.views_used, 13);
  // The same 13 views, no view dropped: our corners and model fit at least as well.
  EXPECT_LE(all.rms_px, sample.rms_px);
  // The command's result (outliers dropped) too.
  EXPECT_LE(f.rms_px, sample.rms_px);
  EXPECT_GE(f.views_used, 9);
  // A kept view's error is what the hold-out predicts for it, within a factor of 2:
  // the fit does not lean on any one view.
  for (const ViewFigures& v : ours.views)
    if (v.used) {
      EXPECT_LT(v.holdout_rms_px, 2.0 * std::max(v.rms_left_px, v.rms_right_px)) << v.name;
    }
  EXPECT_LT(f.holdout_rms_px, 1.5 * f.rms_px);
  EXPECT_LT(f.epipolar_rectified_px, f.rms_px);
  // Triangulated board: neighbouring corners one square (25 mm) apart, within 1 %.
  EXPECT_NEAR(f.square_measured_m / 0.025, 1.0, 0.01);
  // The pair in these images: about 8 cm apart side by side, cameras nearly parallel.
  EXPECT_NEAR(f.calibration.T_camR_camL.translation().norm(), 0.083, 0.005);
  EXPECT_LT(Eigen::AngleAxisd(f.calibration.T_camR_camL.linear()).angle(), 0.05);
}

// The board moved between the left and right exposures of one pair (right06 replaced
// by right07): that view cannot fit any stereo geometry and must be rejected.
TEST_F(RealPairs, ViewThatSpoilsTheFitIsRejected) {
  fs::copy_file(kOpenCvData / "right07.jpg", dir_.path() / "right06.jpg",
                fs::copy_options::overwrite_existing);
  const StereoCalibrationRun run = calibrate_stereo_images(dir_.path(), board_9x6());
  const ViewFigures* six = nullptr;
  for (const ViewFigures& v : run.views)
    if (v.name == "06") six = &v;
  ASSERT_NE(six, nullptr);
  EXPECT_FALSE(six->used);
  EXPECT_EQ(six->rejected_because.rfind("outlier: view RMS", 0), 0u) << six->rejected_because;
  EXPECT_GT(six->holdout_rms_px, 5.0 * run.fit.rms_px);
  for (const ViewFigures& v : run.views)
    std::printf("  view %s used %d left %.3f right %.3f hold-out %.3f %s\n", v.name.c_str(), v.used,
                v.rms_left_px, v.rms_right_px, v.holdout_rms_px, v.rejected_because.c_str());
  // Without it the fit is as good as on the clean images of the other 12 pairs.
  std::vector<ImagePair> clean = find_image_pairs(kOpenCvData);
  ASSERT_EQ(clean.size(), 13u);
  clean.erase(clean.begin() + 5);
  ASSERT_EQ(clean[5].name, "07");
  const StereoFit clean_fit = fit_all_views(clean);
  std::printf("spoiled set: %d views kept, RMS %.4f px; clean 12 pairs, no rejection: RMS %.4f px\n",
              run.fit.views_used, run.fit.rms_px, clean_fit.rms_px);
  EXPECT_LE(run.fit.rms_px, clean_fit.rms_px * 1.001);
  EXPECT_NEAR(run.fit.calibration.T_camR_camL.translation().norm(),
              clean_fit.calibration.T_camR_camL.translation().norm(), 0.001);
  EXPECT_NEAR(run.fit.square_measured_m / 0.025, 1.0, 0.01);
}

// A chessboard found from the other end in one image is put back in the other's order.
TEST_F(RealPairs, ChessboardOrderAgreesBetweenCameras) {
  const TargetSpec t = board_9x6();
  const cv::Mat l = cv::imread((dir_.path() / "left04.jpg").string(), cv::IMREAD_GRAYSCALE);
  const cv::Mat r = cv::imread((dir_.path() / "right04.jpg").string(), cv::IMREAD_GRAYSCALE);
  const Detection dl = detect_target(t, l), dr = detect_target(t, r);
  ASSERT_TRUE(dl.found && dr.found);
  Detection flipped = dr;
  std::reverse(flipped.corners.begin(), flipped.corners.end());
  const StereoView a = stereo_view(t, "04", dl, dr), b = stereo_view(t, "04", dl, flipped);
  ASSERT_EQ(a.right.size(), 54u);
  for (std::size_t i = 0; i < a.right.size(); ++i) EXPECT_EQ(a.right[i], b.right[i]) << i;
  // The same physical corner first in both: nearer to each other than to the far end.
  EXPECT_LT(cv::norm(a.left[0] - a.right[0]), cv::norm(a.left[0] - a.right[53]));
}

// A pair whose right image shows no board is listed with the reason, not fitted.
TEST_F(RealPairs, PairWithoutBoardIsListedWithReason) {
  cv::Mat blank(480, 640, CV_8UC1, cv::Scalar(128));
  ASSERT_TRUE(cv::imwrite((dir_.path() / "right03.jpg").string(), blank));
  const StereoCalibrationRun run = calibrate_stereo_images(dir_.path(), board_9x6());
  ASSERT_EQ(run.views.size(), 13u);
  EXPECT_EQ(run.views[2].name, "03");
  EXPECT_FALSE(run.views[2].used);
  EXPECT_EQ(run.views[2].rejected_because, "right: no 9x6 chessboard found");
}

}  // namespace
}  // namespace dentmark::calibrate
