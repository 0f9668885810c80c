// The stereo.yaml the calibration writes, read back by the tracker's loader, and the
// loader's refusals: each names the file and the field.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <opencv2/calib3d.hpp>

#include "../support/temp_dir.h"
#include "dentmark/firmware/calibrate/stereo_calibration_file.h"
#include "dentmark/firmware/track/track_error.h"

namespace dentmark::calibrate {
namespace {

namespace fs = std::filesystem;

StereoCalibrationRun example_run() {
  StereoCalibrationRun run;
  run.target = parse_target("chessboard:9x6", 0.025, 0.0, "");
  track::StereoCalibration& c = run.fit.calibration;
  c.size = {640, 480};
  c.left.K = cv::Matx33d(533.1, 0, 341.7, 0, 533.4, 234.2, 0, 0, 1);
  c.left.D = (cv::Mat_<double>(1, 5) << -0.28, 0.09, 0.0012, -0.0003, 0.02);
  c.right.K = cv::Matx33d(537.2, 0, 326.9, 0, 536.8, 250.1, 0, 0, 1);
  c.right.D = (cv::Mat_<double>(1, 5) << -0.27, 0.05, -0.0001, 0.0002, 0.06);
  cv::Matx33d r;
  cv::Rodrigues(cv::Vec3d(0.006, 0.004, -0.003), r);
  Eigen::Matrix3d re;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) re(i, j) = r(i, j);
  c.T_camR_camL.linear() = re;
  c.T_camR_camL.translation() = Eigen::Vector3d(-0.0833, 0.0012, 0.0004);
  run.fit.rms_px = 0.23, run.fit.rms_left_px = 0.22, run.fit.rms_right_px = 0.24;
  run.fit.epipolar_rectified_px = 0.11, run.fit.epipolar_rectified_max_px = 1.07;
  run.fit.holdout_rms_px = 0.25, run.fit.holdout_max_view_px = 0.38;
  run.fit.square_given_m = 0.025, run.fit.square_measured_m = 0.02501;
  run.fit.views_used = 2;
  ViewFigures a{"01", true, "", 0.2, 0.3, 0.31},
      b{"02", false, "outlier: view RMS 0.9 px over the limit 0.4 px", 0.8, 1.0, 0.9};
  run.views = {a, b};
  run.inputs_sha256 = std::string(64, 'a');
  run.created_utc = "2026-12-05T19:30:00Z";
  run.tool_version = "0.1.0";
  return run;
}

std::string load_error(const fs::path& p, const track::StereoResidualLimits& limits = {}) {
  try {
    track::load_stereo_calibration(p, limits);
  } catch (const track::TrackError& e) {
    return e.what();
  }
  return "(loaded)";
}

// Writes example_run's file with one field replaced (or removed, for an empty Mat or
// a NaN number passed as 'remove').
class CalibrationFile : public ::testing::Test {
 protected:
  fs::path write_with(const std::string& field, const std::function<void(cv::FileStorage&)>& value) {
    const StereoCalibrationRun run = example_run();
    cv::FileStorage in(stereo_calibration_yaml(run), cv::FileStorage::READ | cv::FileStorage::MEMORY);
    const fs::path p = dir_.path() / ("bad_" + field + ".yaml");
    cv::FileStorage out(p.string(), cv::FileStorage::WRITE);
    for (const cv::FileNode& n : in.root()) {
      const std::string key = n.name();
      if (key == field) {
        if (value) value(out);
        continue;
      }
      if (key == "views" || key == "target" || key == "date" || key == "inputs_sha256" ||
          key == "tool_version")
        continue;  // not read by the loader
      if (n.isMap()) {
        cv::Mat m;
        n >> m;
        out << key << m;
      } else if (n.isInt()) {
        out << key << static_cast<int>(n);
      } else {
        out << key << static_cast<double>(n);
      }
    }
    out.release();
    return p;
  }
  ::dentmark::test::TempDir dir_{"calib-file"};
};

TEST_F(CalibrationFile, WrittenFileLoadsWithTheSameValues) {
  const StereoCalibrationRun run = example_run();
  const fs::path p = dir_.path() / "stereo.yaml";
  write_stereo_calibration(p.string(), run);
  const track::StereoCalibration c = track::load_stereo_calibration(p);
  EXPECT_EQ(c.size, run.fit.calibration.size);
  EXPECT_LT(cv::norm(cv::Mat(c.left.K), cv::Mat(run.fit.calibration.left.K)), 1e-12);
  EXPECT_LT(cv::norm(cv::Mat(c.right.K), cv::Mat(run.fit.calibration.right.K)), 1e-12);
  EXPECT_LT(cv::norm(c.left.D, run.fit.calibration.left.D), 1e-15);
  EXPECT_LT(cv::norm(c.right.D, run.fit.calibration.right.D), 1e-15);
  EXPECT_TRUE(c.T_camR_camL.isApprox(run.fit.calibration.T_camR_camL, 1e-12));
  // Only the file: the temporary one was renamed into place.
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_.path()), fs::directory_iterator()), 1);
  // Provenance and per-view figures are in the file.
  cv::FileStorage fs(p.string(), cv::FileStorage::READ);
  EXPECT_EQ(static_cast<std::string>(fs["date"]), "2026-12-05T19:30:00Z");
  EXPECT_EQ(static_cast<std::string>(fs["inputs_sha256"]), std::string(64, 'a'));
  EXPECT_EQ(static_cast<std::string>(fs["tool_version"]), "0.1.0");
  EXPECT_EQ(static_cast<std::string>(fs["views"][1]["rejected_because"]),
            "outlier: view RMS 0.9 px over the limit 0.4 px");
  EXPECT_DOUBLE_EQ(static_cast<double>(fs["views"][0]["holdout_rms_px"]), 0.31);
}

TEST_F(CalibrationFile, RefusesMissingMatrix) {
  const fs::path p = write_with("K2", nullptr);
  EXPECT_EQ(load_error(p), p.string() + ": field K2 is missing");
}

TEST_F(CalibrationFile, RefusesWrongShapedMatrix) {
  fs::path p = write_with("K1", [](cv::FileStorage& f) { f << "K1" << cv::Mat(cv::Mat::eye(2, 3, CV_64F)); });
  EXPECT_EQ(load_error(p), p.string() + ": field K1 must be 3x3");
  p = write_with("T", [](cv::FileStorage& f) { f << "T" << cv::Mat(cv::Mat::ones(2, 1, CV_64F)); });
  EXPECT_EQ(load_error(p), p.string() + ": field T must have 3 elements");
  p = write_with("D2", [](cv::FileStorage& f) { f << "D2" << cv::Mat(cv::Mat::zeros(1, 6, CV_64F)); });
  EXPECT_EQ(load_error(p), p.string() + ": field D2 must hold 4, 5, 8, 12 or 14 coefficients, has 6");
}

TEST_F(CalibrationFile, RefusesReflection) {
  const fs::path p = write_with("R", [](cv::FileStorage& f) {
    f << "R" << cv::Mat(cv::Mat::diag((cv::Mat_<double>(3, 1) << 1, 1, -1)));
  });
  EXPECT_EQ(load_error(p).rfind(p.string() + ": field R is not a rotation (determinant -1", 0), 0u)
      << load_error(p);
}

TEST_F(CalibrationFile, RefusesNonOrthonormalR) {
  const fs::path p =
      write_with("R", [](cv::FileStorage& f) { f << "R" << cv::Mat(1.01 * cv::Mat::eye(3, 3, CV_64F)); });
  EXPECT_EQ(load_error(p), p.string() + ": field R is not a rotation (not orthonormal: |R^T R - I| > 1e-3)");
}

TEST_F(CalibrationFile, RefusesNonFiniteValues) {
  fs::path p = write_with("K1", [](cv::FileStorage& f) {
    f << "K1" << cv::Mat((cv::Mat_<double>(3, 3) << NAN, 0, 320, 0, 500, 240, 0, 0, 1));
  });
  EXPECT_EQ(load_error(p), p.string() + ": field K1 has a non-finite value");
  p = write_with(
      "T", [](cv::FileStorage& f) { f << "T" << cv::Mat((cv::Mat_<double>(3, 1) << -0.08, INFINITY, 0)); });
  EXPECT_EQ(load_error(p), p.string() + ": field T has a non-finite value");
  p = write_with("rms_px", [](cv::FileStorage& f) { f << "rms_px" << NAN; });
  EXPECT_EQ(load_error(p).rfind(p.string() + ": field rms_px is not a residual", 0), 0u) << load_error(p);
}

TEST_F(CalibrationFile, RefusesResidualsOverTheLimits) {
  fs::path p = write_with("rms_px", [](cv::FileStorage& f) { f << "rms_px" << 1.5; });
  EXPECT_EQ(load_error(p),
            p.string() + ": field rms_px is 1.500 px, over the limit of 1.000 px: recalibrate");
  p = write_with("epipolar_rectified_px", [](cv::FileStorage& f) { f << "epipolar_rectified_px" << 1.2; });
  EXPECT_EQ(
      load_error(p),
      p.string() + ": field epipolar_rectified_px is 1.200 px, over the limit of 1.000 px: recalibrate");
  p = write_with("holdout_rms_px", [](cv::FileStorage& f) { f << "holdout_rms_px" << 2.5; });
  EXPECT_EQ(load_error(p),
            p.string() + ": field holdout_rms_px is 2.500 px, over the limit of 2.000 px: recalibrate");
  // The limits are the caller's: a stricter station refuses what the default accepts.
  p = write_with("rms_px", [](cv::FileStorage& f) { f << "rms_px" << 0.5; });
  EXPECT_EQ(load_error(p), "(loaded)");
  track::StereoResidualLimits strict;
  strict.max_rms_px = 0.4;
  EXPECT_EQ(load_error(p, strict),
            p.string() + ": field rms_px is 0.500 px, over the limit of 0.400 px: recalibrate");
}

TEST_F(CalibrationFile, OurFilesMustRecordTheirResiduals) {
  const fs::path p = write_with("rms_px", nullptr);
  EXPECT_EQ(load_error(p), p.string() + ": field rms_px is missing");
  // A hold-out that was not computed is written as −1 and accepted.
  const fs::path q = write_with("holdout_rms_px", [](cv::FileStorage& f) { f << "holdout_rms_px" << -1.0; });
  EXPECT_EQ(load_error(q), "(loaded)");
}

}  // namespace
}  // namespace dentmark::calibrate
