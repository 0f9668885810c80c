// The ground-truth side of the scanner calibration's twin test (scanner_twin.sh):
// renders captures of the scanner target with the twin's renderers, and judges a
// scanner.yaml against the truth. Not part of the station: only the test sees the truth.
//   scanner_twin scene DIR CAPTURES SEED
//       DIR/cal/stereo.yaml (the twin's rig, exact), DIR/target.yaml (the target's
//       drawing), DIR/captures/{scan<N>.ply,left<N>.png,right<N>.png} and
//       DIR/truth.yaml (T_camL_sls). The target is placed CAPTURES times near the
//       door's scan position A (2.8 m from camL), tilted by up to 0.25 rad
//       (simulation::render_scanner_captures: the images from sim's ChessboardRenderer,
//       the scans from sim's sphere_target_scan).
//   scanner_twin check DIR SCANNER_YAML MAX_TRANSLATION_M MAX_GRID_RMS_M MAX_ROTATION_RAD
//       the file's T_camL_sls against the truth: the translation error (the sensor's
//       origin, 0.9 m in front of the door), the rotation error, and the point transfer
//       error of a 1.2 × 0.8 m grid of points where the scanner sees the door (about
//       2.8 m from camL). Exits 0 when each is within its bound, else 1 naming it.
#include <Eigen/Core>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/core/eigen.hpp>
#include <string>

#include "dentmark/firmware/calibrate/scanner_calibration.h"
#include "dentmark/firmware/simulation/self_calibration.h"
#include "dentmark/sim/calibration/calibration_scene.h"

using namespace dentmark;
namespace fs = std::filesystem;

namespace {

// The twin's door position A (workcell.cpp: 0.27 m before B) and the scanner 0.9 m in
// front of it, up and to the left, looking at it.
const Eigen::Vector3d kPositionA(0.5 * 0.5 - 0.17 - 0.27, 0.1, 2.8);

Transform true_T_camL_sls() {
  const Eigen::Vector3d p(-0.55, -0.25, 2.0);
  const Eigen::Vector3d z = (kPositionA - p).normalized();
  const Eigen::Vector3d x = Eigen::Vector3d::UnitY().cross(z).normalized();
  Eigen::Matrix3d r;
  r << x, z.cross(x), z;
  return make_transform(r, p);
}

void write_transform(const fs::path& path, const Transform& t) {
  cv::FileStorage out(path.string(), cv::FileStorage::WRITE);
  cv::Mat m;
  cv::eigen2cv(Eigen::Matrix4d(t.matrix()), m);
  out << "T_camL_sls" << m;
}

int scene(const fs::path& dir, int captures, std::uint64_t seed) {
  const sim::stereo::StereoRig rig = sim::calibration::twin_calibration_scene().rig;
  fs::create_directories(dir / "cal");
  fs::create_directories(dir / "captures");
  sim::stereo::write_stereo_yaml(rig, dir / "cal" / "stereo.yaml");
  const Transform T_camL_sls = true_T_camL_sls();
  write_transform(dir / "truth.yaml", T_camL_sls);
  simulation::render_scanner_captures(rig, T_camL_sls, kPositionA, captures, seed, dir / "captures",
                                      dir / "target.yaml");
  return 0;
}

int check(const fs::path& dir, const fs::path& scanner_yaml, double max_t, double max_grid, double max_r) {
  cv::FileStorage in((dir / "truth.yaml").string(), cv::FileStorage::READ);
  cv::Mat m;
  in["T_camL_sls"] >> m;
  Eigen::Matrix4d e;
  cv::cv2eigen(m, e);
  Transform truth = Transform::Identity();
  truth.matrix() = e;
  const Transform est = calibrate::load_scanner_calibration(scanner_yaml);
  const double dt = (est.translation() - truth.translation()).norm();
  const double dr = Eigen::AngleAxisd((truth.inverse() * est).linear()).angle();
  double ss = 0.0, worst = 0.0;
  int n = 0;
  for (double x = -0.6; x <= 0.6001; x += 0.1)
    for (double y = -0.4; y <= 0.4001; y += 0.1) {
      const Eigen::Vector3d p_sls(x, y, 0.9);
      const double err = (est * p_sls - truth * p_sls).norm();
      ss += err * err, worst = std::max(worst, err), ++n;
    }
  const double rms = std::sqrt(ss / n);
  std::printf(
      "against the truth: T_camL_sls translation off by %.3f mm, rotation by %.3f mrad; point transfer on "
      "the "
      "door's %d-point 1.2 x 0.8 m grid at %.2f m from camL: RMS %.3f mm, max %.3f mm\n",
      dt * 1e3, dr * 1e3, n, (truth * Eigen::Vector3d(0, 0, 0.9)).norm(), rms * 1e3, worst * 1e3);
  int bad = 0;
  if (!(dt <= max_t)) std::printf("translation %.3f mm > %.3f mm\n", dt * 1e3, max_t * 1e3), bad = 1;
  if (!(rms <= max_grid))
    std::printf("door grid RMS %.3f mm > %.3f mm\n", rms * 1e3, max_grid * 1e3), bad = 1;
  if (!(dr <= max_r)) std::printf("rotation %.3f mrad > %.3f mrad\n", dr * 1e3, max_r * 1e3), bad = 1;
  return bad;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::string cmd = argc > 1 ? argv[1] : "";
    if (cmd == "scene" && argc == 5) return scene(argv[2], std::stoi(argv[3]), std::stoull(argv[4]));
    if (cmd == "check" && argc == 7)
      return check(argv[2], argv[3], std::stod(argv[4]), std::stod(argv[5]), std::stod(argv[6]));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "scanner_twin: %s\n", e.what());
    return 2;
  }
  std::fprintf(
      stderr,
      "usage: scanner_twin scene DIR CAPTURES SEED | check DIR SCANNER_YAML MAX_T_M MAX_GRID_M MAX_RAD\n");
  return 2;
}
