#pragma once
// A station's calibration folder (docs/calibration.md), what the daemon needs to turn
// a defect in the scan into a tool pose (design.md §2):
//   stereo.yaml              the tracking pair: K1 D1 K2 D2 R T, image size
//   robot.yaml               T_base_camL, the paper's Q_CB (robot-to-stereo)
//   scanner.yaml             T_camL_sls (scanner-to-stereo)
//   models/<panel_id>.yaml   taught panel models (`dentmark-edge teach`)
// Transform files are OpenCV FileStorage YAML with a 4×4 matrix under the transform's
// name (T_base_camL or T_camL_sls), its residual `rms` (m), `date` and `tool_version`.

#include <filesystem>
#include <stdexcept>
#include <string>

#include "dentmark/common/geometry/transform.h"
#include "dentmark/firmware/track/stereo_calibration.h"

namespace dentmark::station {

class CalibrationError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct StationCalibration {
  track::StereoCalibration stereo;
  Transform T_base_camL = Transform::Identity();
  Transform T_camL_sls = Transform::Identity();
  std::filesystem::path models_dir;
};

// Reads and checks the folder. Throws CalibrationError naming the file and field: a
// missing file or matrix, a matrix not 4×4, a bottom row not (0 0 0 1), a rotation part
// that is not a proper rotation (|RᵀR − I| > 1e-6 or det ≠ +1), non-finite values, a
// translation beyond 100 m, or a recorded rms over `max_rms` (m).
StationCalibration load_station_calibration(const std::filesystem::path& dir, double max_rms = 0.005);

// One transform file (see above).
Transform load_transform(const std::filesystem::path& path, const std::string& name, double max_rms = 0.005);
// Writes one transform file atomically.
void save_transform(const std::filesystem::path& path, const std::string& name, const Transform& T,
                    double rms);

}  // namespace dentmark::station
