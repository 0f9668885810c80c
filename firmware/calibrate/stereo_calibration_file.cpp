#include "dentmark/firmware/calibrate/stereo_calibration_file.h"

#include <cmath>
#include <nlohmann/json.hpp>
#include <opencv2/core/eigen.hpp>

#include "dentmark/common/atomic_file.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"

namespace dentmark::calibrate {
namespace {

cv::Mat rotation(const StereoCalibrationRun& run) {
  cv::Mat r;
  cv::eigen2cv(Eigen::Matrix3d(run.fit.calibration.T_camR_camL.linear()), r);
  return r;
}
cv::Mat translation(const StereoCalibrationRun& run) {
  cv::Mat t;
  cv::eigen2cv(Eigen::Vector3d(run.fit.calibration.T_camR_camL.translation()), t);
  return t;
}

// FileStorage and JSON have no NaN: a figure that was not computed is written as -1.
double figure(double v) {
  return std::isfinite(v) ? v : -1.0;
}

nlohmann::json matrix_json(const cv::Mat& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (int i = 0; i < m.rows; ++i) {
    nlohmann::json row = nlohmann::json::array();
    for (int j = 0; j < m.cols; ++j) row.push_back(m.at<double>(i, j));
    rows.push_back(row);
  }
  return rows;
}

}  // namespace

std::string stereo_calibration_yaml(const StereoCalibrationRun& run) {
  const StereoFit& f = run.fit;
  const track::StereoCalibration& c = f.calibration;
  cv::FileStorage fs(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
  fs << "dentmark_stereo_calibration" << kStereoFileVersion;
  fs << "image_width" << c.size.width << "image_height" << c.size.height;
  fs << "K1" << cv::Mat(c.left.K) << "D1" << c.left.D << "K2" << cv::Mat(c.right.K) << "D2" << c.right.D;
  fs << "R" << rotation(run) << "T" << translation(run);
  fs << "rms_px" << figure(f.rms_px) << "rms_left_px" << figure(f.rms_left_px) << "rms_right_px"
     << figure(f.rms_right_px);
  fs << "epipolar_rectified_px" << figure(f.epipolar_rectified_px) << "epipolar_rectified_max_px"
     << figure(f.epipolar_rectified_max_px);
  fs << "holdout_rms_px" << figure(f.holdout_rms_px) << "holdout_max_view_px"
     << figure(f.holdout_max_view_px);
  fs << "square_given_m" << figure(f.square_given_m) << "square_measured_m" << figure(f.square_measured_m);
  fs << "views_used" << f.views_used << "views_total" << static_cast<int>(run.views.size());
  fs << "views"
     << "[";
  for (const ViewFigures& v : run.views) {
    fs << "{"
       << "name" << v.name << "used" << static_cast<int>(v.used) << "rms_left_px" << figure(v.rms_left_px)
       << "rms_right_px" << figure(v.rms_right_px) << "holdout_rms_px" << figure(v.holdout_rms_px);
    if (!v.used) fs << "rejected_because" << v.rejected_because;
    fs << "}";
  }
  fs << "]";
  fs << "target" << run.target.describe() << "date" << run.created_utc << "inputs_sha256" << run.inputs_sha256
     << "tool_version" << run.tool_version;
  return fs.releaseAndGetString();
}

std::string stereo_calibration_json(const StereoCalibrationRun& run) {
  const StereoFit& f = run.fit;
  const track::StereoCalibration& c = f.calibration;
  nlohmann::json j;
  j["image_width"] = c.size.width;
  j["image_height"] = c.size.height;
  j["K1"] = matrix_json(cv::Mat(c.left.K));
  j["D1"] = matrix_json(c.left.D);
  j["K2"] = matrix_json(cv::Mat(c.right.K));
  j["D2"] = matrix_json(c.right.D);
  j["R"] = matrix_json(rotation(run));
  j["T"] = matrix_json(translation(run).reshape(1, 1));
  j["baseline_m"] = cv::norm(translation(run));
  j["rms_px"] = figure(f.rms_px);
  j["rms_left_px"] = figure(f.rms_left_px);
  j["rms_right_px"] = figure(f.rms_right_px);
  j["epipolar_rectified_px"] = figure(f.epipolar_rectified_px);
  j["epipolar_rectified_max_px"] = figure(f.epipolar_rectified_max_px);
  j["holdout_rms_px"] = figure(f.holdout_rms_px);
  j["holdout_max_view_px"] = figure(f.holdout_max_view_px);
  j["square_given_m"] = figure(f.square_given_m);
  j["square_measured_m"] = figure(f.square_measured_m);
  j["views_used"] = f.views_used;
  j["views_total"] = run.views.size();
  j["views"] = nlohmann::json::array();
  for (const ViewFigures& v : run.views) {
    nlohmann::json jv{{"name", v.name},
                      {"used", v.used},
                      {"rms_left_px", figure(v.rms_left_px)},
                      {"rms_right_px", figure(v.rms_right_px)},
                      {"holdout_rms_px", figure(v.holdout_rms_px)}};
    if (!v.used) jv["rejected_because"] = v.rejected_because;
    j["views"].push_back(jv);
  }
  j["target"] = run.target.describe();
  j["date"] = run.created_utc;
  j["inputs_sha256"] = run.inputs_sha256;
  j["tool_version"] = run.tool_version;
  return j.dump(2);
}

void write_stereo_calibration(const std::string& path, const StereoCalibrationRun& run) {
  try {
    files::write_atomically(path, stereo_calibration_yaml(run));
  } catch (const files::FileError& e) {
    throw CalibrateError(e.what());
  }
}

}  // namespace dentmark::calibrate
