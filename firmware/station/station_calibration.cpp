#include "dentmark/firmware/station/station_calibration.h"

#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>

#include "dentmark/common/atomic_file.h"
#include "dentmark/common/utc_time.h"
#include "dentmark/common/version.h"
#include "dentmark/common/yaml_file.h"
#include "dentmark/firmware/track/track_error.h"

namespace dentmark::station {
namespace fs = std::filesystem;

Transform load_transform(const fs::path& path, const std::string& name, double max_rms) {
  const std::string file = path.string();
  cv::FileStorage in = files::open_yaml_or_throw<CalibrationError>(path);
  const cv::FileNode node = in[name];
  if (node.empty()) throw CalibrationError(file + ": field " + name + " is missing");
  cv::Mat m;
  try {
    node >> m;
  } catch (const cv::Exception&) {
    throw CalibrationError(file + ": field " + name + " is not a matrix");
  }
  if (m.rows != 4 || m.cols != 4)
    throw CalibrationError(file + ": field " + name + " must be 4x4, is " + std::to_string(m.rows) + "x" +
                           std::to_string(m.cols));
  m.convertTo(m, CV_64F);
  Eigen::Matrix4d e;
  cv::cv2eigen(m, e);
  if (!e.allFinite()) throw CalibrationError(file + ": field " + name + " has non-finite values");
  if ((e.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-12)
    throw CalibrationError(file + ": field " + name + ": bottom row must be 0 0 0 1");
  const Eigen::Matrix3d r = e.topLeftCorner<3, 3>();
  if ((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6 ||
      std::abs(r.determinant() - 1.0) > 1e-6)
    throw CalibrationError(file + ": field " + name + ": the rotation part is not a proper rotation");
  if (e.topRightCorner<3, 1>().norm() > 100.0)
    throw CalibrationError(file + ": field " + name + ": translation beyond 100 m (not metres?)");
  const cv::FileNode rms = in["rms"];
  if (!rms.empty()) {
    if (!rms.isReal() && !rms.isInt()) throw CalibrationError(file + ": field rms is not a number");
    const double v = static_cast<double>(rms);
    if (!std::isfinite(v) || v < 0) throw CalibrationError(file + ": field rms must be finite and >= 0");
    if (v > max_rms)
      throw CalibrationError(file + ": recorded residual rms " + std::to_string(v * 1e3) + " mm exceeds " +
                             std::to_string(max_rms * 1e3) + " mm: recalibrate");
  }
  Transform T = Transform::Identity();
  T.linear() = r;
  T.translation() = e.topRightCorner<3, 1>();
  return T;
}

void save_transform(const fs::path& path, const std::string& name, const Transform& T, double rms) {
  cv::FileStorage out(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
  cv::Mat m;
  const Eigen::Matrix4d e = T.matrix();
  cv::eigen2cv(e, m);
  out << name << m;
  out << "rms" << rms;
  out << "date" << utc_now_iso8601();
  out << "tool_version" << std::string(kVersion);
  files::write_atomically(path, out.releaseAndGetString());
}

StationCalibration load_station_calibration(const fs::path& dir, double max_rms) {
  if (!fs::is_directory(dir)) throw CalibrationError(dir.string() + ": not a calibration folder");
  StationCalibration c;
  try {
    c.stereo = track::load_stereo_calibration(dir / "stereo.yaml");
  } catch (const track::TrackError& e) {
    throw CalibrationError(e.what());
  }
  c.T_base_camL = load_transform(dir / "robot.yaml", "T_base_camL", max_rms);
  c.T_camL_sls = load_transform(dir / "scanner.yaml", "T_camL_sls", max_rms);
  c.models_dir = dir / "models";
  return c;
}

}  // namespace dentmark::station
