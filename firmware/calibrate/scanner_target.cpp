#include "dentmark/firmware/calibrate/scanner_target.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/core.hpp>

#include "dentmark/common/atomic_file.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"
#include "dentmark/firmware/calibrate/calibration_yaml.h"
#include "dentmark/firmware/calibrate/target_measurement.h"

namespace dentmark::calibrate {
namespace {

constexpr double kMinDistanceContrast = 0.020;  // m between any two pairwise distances

double number(const cv::FileStorage& fs, const std::string& file, const char* name) {
  const cv::FileNode n = fs[name];
  if (n.empty() || n.isNone()) throw CalibrateError(file + ": field " + name + " is missing");
  if (!(n.isReal() || n.isInt())) throw CalibrateError(file + ": field " + name + " is not a number");
  const double v = n.real();
  if (!std::isfinite(v)) throw CalibrateError(file + ": field " + name + " is not finite");
  return v;
}

}  // namespace

void check_scanner_target(const ScannerTarget& t, const std::string& where) {
  if (t.board.kind != TargetKind::kChessboard)
    throw CalibrateError(where + ": field pattern: the scanner target is a chessboard");
  try {
    require_oriented_chessboard(t.board);
  } catch (const CalibrateError& e) {
    throw CalibrateError(where + ": field pattern: " + e.what());
  }
  const double r = t.sphere_radius_m;
  if (!(r >= 0.005 && r <= 0.1))
    throw CalibrateError(where + ": field sphere_radius: " + std::to_string(r) + " m is outside 0.005-0.1 m");
  const std::size_t n = t.spheres_board.size();
  if (n < 4 || n > 8)
    throw CalibrateError(where + ": field spheres_board: " + std::to_string(n) +
                         " spheres; the target needs 4 to 8 (3 fit exactly and leave nothing to check)");
  std::vector<double> d;
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i + 1; j < n; ++j) {
      const double dij = (t.spheres_board[i] - t.spheres_board[j]).norm();
      if (dij < 2.5 * r) {
        char b[160];
        std::snprintf(b, sizeof b,
                      ": field spheres_board: spheres %zu and %zu are %.1f mm apart (< 2.5 radii)", i, j,
                      dij * 1e3);
        throw CalibrateError(where + b);
      }
      d.push_back(dij);
    }
  std::sort(d.begin(), d.end());
  for (std::size_t k = 1; k < d.size(); ++k)
    if (d[k] - d[k - 1] < kMinDistanceContrast) {
      char b[200];
      std::snprintf(
          b, sizeof b,
          ": field spheres_board: two sphere pairs are %.1f and %.1f mm apart; the layout needs every "
          "pairwise distance distinct by %.0f mm (else the scan's spheres match it ambiguously)",
          d[k - 1] * 1e3, d[k] * 1e3, kMinDistanceContrast * 1e3);
      throw CalibrateError(where + b);
    }
}

ScannerTarget read_scanner_target(const std::filesystem::path& path) {
  const std::string file = path.string();
  cv::FileStorage fs = open_yaml(path);
  const cv::FileNode pattern = fs["pattern"];
  if (pattern.empty() || !pattern.isString())
    throw CalibrateError(file + ": field pattern is missing (a string, e.g. chessboard:9x6)");
  ScannerTarget t;
  try {
    t.board = parse_target(pattern.string(), number(fs, file, "square"), 0.0, "");
  } catch (const CalibrateError& e) {
    if (std::string(e.what()).rfind(file, 0) == 0) throw;
    throw CalibrateError(file + ": field pattern/square: " + e.what());
  }
  t.sphere_radius_m = number(fs, file, "sphere_radius");
  t.spheres_board = read_points(fs["spheres_board"], file, "spheres_board");
  check_scanner_target(t, file);
  return t;
}

void write_scanner_target(const std::filesystem::path& path, const ScannerTarget& t) {
  cv::FileStorage fs(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
  fs << "pattern" << ("chessboard:" + std::to_string(t.board.cols) + "x" + std::to_string(t.board.rows));
  fs << "square" << t.board.square_m << "sphere_radius" << t.sphere_radius_m;
  cv::Mat m(static_cast<int>(t.spheres_board.size()), 3, CV_64F);
  for (std::size_t i = 0; i < t.spheres_board.size(); ++i)
    for (int k = 0; k < 3; ++k) m.at<double>(static_cast<int>(i), k) = t.spheres_board[i](k);
  fs << "spheres_board" << m;
  try {
    files::write_atomically(path, fs.releaseAndGetString());
  } catch (const files::FileError& e) {
    throw CalibrateError(e.what());
  }
}

}  // namespace dentmark::calibrate
