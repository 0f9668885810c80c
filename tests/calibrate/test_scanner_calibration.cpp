// The scanner calibration (T_camL_sls) on captures from a second generator sharing no
// code with the twin's (sim/calibration): the image pairs from the tests' own planar
// renderer (stereo_renderer.h: texture warped by the plane homography, supersampled,
// blur and Gaussian noise; its own rig without distortion), the scans as text XYZ files
// in millimetres written here: points drawn area-uniformly at random on the plate and on
// the spheres' faces the sensor sees (no stems: balls on magnets), isotropic Gaussian
// noise of 80 µm, 0.5 % outliers anywhere in the target's box. Another target (7×6
// board of 50 mm squares, 25.4 mm balls), rig, scanner pose and truth.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <random>

#include "../support/temp_dir.h"
#include "dentmark/firmware/calibrate/board_pose.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"
#include "dentmark/firmware/calibrate/scanner_calibration.h"
#include "dentmark/firmware/station/station_calibration.h"
#include "stereo_renderer.h"

namespace dentmark::calibrate {
namespace {

struct SecondScene {
  cv::Size size{1280, 960};
  cv::Matx33d K[2] = {{1650, 0, 641, 0, 1650, 482, 0, 0, 1}, {1648, 0, 636, 0, 1648, 476, 0, 0, 1}};
  Transform T_camR_camL =
      make_transform_rotvec(Eigen::Vector3d(0.01, 0.165, 0.004), Eigen::Vector3d(-0.42, 0.01, 0.035));
  // The scanner 1.1 m in front of the target, right of and below the cameras' axis.
  Transform T_camL_sls =
      make_transform_rotvec(Eigen::Vector3d(0.2, -0.35, 0.05), Eigen::Vector3d(0.75, 0.35, 1.45));
  ScannerTarget target;
  Eigen::Vector2d plate_min{-0.20, -0.18}, plate_max{0.50, 0.45};

  SecondScene() {
    target.board = parse_target("chessboard:7x6", 0.05, 0, "");
    target.sphere_radius_m = 0.0127;
    target.spheres_board = {{-0.158, -0.058, 0.04},
                            {0.44, -0.097, 0.05},
                            {0.438, 0.19, 0.03},
                            {0.283, -0.135, 0.035},
                            {0.397, 0.396, 0.045}};
  }
};

track::StereoCalibration stereo_of(const SecondScene& s) {
  track::StereoCalibration c;
  c.size = s.size;
  c.left.K = s.K[0];
  c.right.K = s.K[1];
  c.T_camR_camL = s.T_camR_camL;
  return c;
}

// Is the segment from p to the sensor o blocked by a sphere other than 'self'?
bool occluded(const SecondScene& s, const Eigen::Vector3d& p, const Eigen::Vector3d& o, int self) {
  for (int i = 0; i < static_cast<int>(s.target.spheres_board.size()); ++i) {
    if (i == self) continue;
    const Eigen::Vector3d c = s.target.spheres_board[static_cast<std::size_t>(i)], d = o - p;
    const double t = std::clamp((c - p).dot(d) / d.squaredNorm(), 0.0, 1.0);
    if ((p + t * d - c).norm() < s.target.sphere_radius_m) return true;
  }
  return false;
}

// The scan of the target at T_sls_board: "x y z" lines in millimetres.
void write_scan(const SecondScene& s, const Transform& T_sls_board, const std::filesystem::path& path,
                std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> n(0.0, 80e-6);
  const Eigen::Vector3d o = T_sls_board.inverse().translation();  // sensor in the board frame
  std::vector<Eigen::Vector3d> pts;
  const Eigen::Vector2d ext = s.plate_max - s.plate_min;
  for (int k = 0; k < 250000; ++k) {
    const Eigen::Vector3d p(s.plate_min.x() + ext.x() * u(rng), s.plate_min.y() + ext.y() * u(rng), 0.0);
    if (!occluded(s, p, o, -1)) pts.push_back(p);
  }
  const double r = s.target.sphere_radius_m;
  for (int i = 0; i < static_cast<int>(s.target.spheres_board.size()); ++i)
    for (int k = 0; k < 4000; ++k) {
      const Eigen::Vector3d d(n(rng), n(rng), n(rng));  // direction: an isotropic Gaussian normalised
      if (d.norm() < 1e-12) continue;
      const Eigen::Vector3d c = s.target.spheres_board[static_cast<std::size_t>(i)];
      const Eigen::Vector3d p = c + r * d.normalized();
      if (d.dot(o - p) > 0.0 && !occluded(s, p, o, i)) pts.push_back(p);
    }
  std::ofstream out(path);
  out.precision(9);
  for (const Eigen::Vector3d& p : pts) {
    Eigen::Vector3d q = T_sls_board * p + Eigen::Vector3d(n(rng), n(rng), n(rng));
    if (u(rng) < 0.005)
      q = T_sls_board * Eigen::Vector3d(s.plate_min.x() + ext.x() * u(rng),
                                        s.plate_min.y() + ext.y() * u(rng), -0.05 + 0.15 * u(rng));
    out << q.x() * 1e3 << ' ' << q.y() * 1e3 << ' ' << q.z() * 1e3 << '\n';
  }
}

// Captures of the target about 2.5 m in front of camL, tilted; returns nothing, writes DIR.
void write_captures(const SecondScene& s, const std::filesystem::path& dir, int captures) {
  const test::Texture tex =
      test::chessboard_texture(s.target.board.cols, s.target.board.rows, s.target.board.square_m, 48);
  test::RenderSettings rs;
  rs.size = s.size;
  rs.blur_sigma_px = 0.9;
  rs.noise_sigma = 2.5;
  cv::RNG rng(5);
  std::mt19937_64 g(17);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Vector3d centre_board(0.15, 0.135, 0.0);
  for (int k = 1; k <= captures; ++k) {
    const Eigen::Matrix3d r =
        Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix() *
        make_transform_rotvec(Eigen::Vector3d(0.3 * u(g), 0.3 * u(g), 0.2 * u(g)), Eigen::Vector3d::Zero())
            .linear();
    const Eigen::Vector3d c(0.15 + 0.1 * u(g), -0.05 + 0.1 * u(g), 2.5 + 0.1 * u(g));
    const Transform T_camL_board = make_transform(r, c - r * centre_board);
    for (int eye = 0; eye < 2; ++eye) {
      const Transform T = (eye == 0 ? Transform::Identity() : s.T_camR_camL) * T_camL_board;
      cv::Matx33d R;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) R(i, j) = T.linear()(i, j);
      const cv::Vec3d t(T.translation().x(), T.translation().y(), T.translation().z());
      cv::imwrite((dir / ((eye == 0 ? "left" : "right") + std::to_string(k) + ".png")).string(),
                  test::render_view(tex, s.K[eye], R, t, rs, rng));
    }
    write_scan(s, s.T_camL_sls.inverse() * T_camL_board, dir / ("scan" + std::to_string(k) + ".xyz"),
               100 + static_cast<std::uint64_t>(k));
  }
}

// Pixels of every corner of 'board' at T_camL_board in both cameras of 's' (no distortion).
BoardView project_board(const SecondScene& s, const TargetSpec& board, const Transform& T_camL_board) {
  BoardView v;
  for (int id = 0; id < board.corner_count(); ++id) {
    const cv::Point3f c = board.corner(id);
    const Eigen::Vector3d p_camL = T_camL_board * Eigen::Vector3d(c.x, c.y, c.z);
    for (int eye = 0; eye < 2; ++eye) {
      const Eigen::Vector3d p = eye == 0 ? p_camL : s.T_camR_camL * p_camL;
      const cv::Point2f px(static_cast<float>(s.K[eye](0, 0) * p.x() / p.z() + s.K[eye](0, 2)),
                           static_cast<float>(s.K[eye](1, 1) * p.y() / p.z() + s.K[eye](1, 2)));
      (eye == 0 ? v.pixels_left : v.pixels_right).push_back(px);
    }
  }
  return v;
}

// The chained refinement finds the one transform shared by several views of the board,
// each at a known pose in the scanner's frame, from a start 5 mm and 10 mrad off: to the
// corners' float rounding with exact pixels.
TEST(ScannerCalibration, ChainedRefinementRecoversTheSharedTransform) {
  const SecondScene s;
  std::vector<BoardView> views;
  const Eigen::Vector3d tilts[3] = {{M_PI + 0.2, 0.1, 0.05}, {M_PI - 0.15, -0.2, 0.0}, {M_PI, 0.25, -0.1}};
  for (int k = 0; k < 3; ++k) {
    const Transform T_camL_board =
        make_transform_rotvec(tilts[k], Eigen::Vector3d(0.1 * (k - 1), 0.05 * k - 0.1, 2.5 + 0.05 * k));
    BoardView v = project_board(s, s.target.board, T_camL_board);
    v.T_x_target = s.T_camL_sls.inverse() * T_camL_board;
    views.push_back(v);
  }
  const Transform start =
      make_transform_rotvec(Eigen::Vector3d(0.006, -0.005, 0.005), Eigen::Vector3d(0.003, -0.003, 0.003)) *
      s.T_camL_sls;
  const ChainedPose p = refine_chained_pose(s.target.board, stereo_of(s), views, start);
  const double dt = (p.T_camL_x.translation() - s.T_camL_sls.translation()).norm();
  const double dr = Eigen::AngleAxisd((s.T_camL_sls.inverse() * p.T_camL_x).linear()).angle();
  EXPECT_LT(dt, 2e-6);
  EXPECT_LT(dr, 2e-6);
  EXPECT_LT(p.rms_px, 1e-3);  // float pixels: about 1e-4 px
}

TEST(ScannerCalibration, SecondGeneratorRecoversTheTruth) {
  const SecondScene s;
  ::dentmark::test::TempDir tmp("scanner");
  write_captures(s, tmp.path(), 3);
  const ScannerCalibrationRun run = calibrate_scanner_captures(tmp.path(), s.target, stereo_of(s), 0.001);
  ASSERT_EQ(run.captures.size(), 3u);
  EXPECT_EQ(run.fit.points, 15);  // every sphere found and matched in every capture
  const Transform& est = run.fit.T_camL_sls;
  const double dt = (est.translation() - s.T_camL_sls.translation()).norm();
  const double dr = Eigen::AngleAxisd((s.T_camL_sls.inverse() * est).linear()).angle();
  // Point transfer where the scanner sees the door: a 1.2 × 0.8 m grid 1.1 m in front of it.
  double ss = 0.0, worst = 0.0;
  int n = 0;
  for (double x = -0.6; x <= 0.6001; x += 0.1)
    for (double y = -0.4; y <= 0.4001; y += 0.1) {
      const Eigen::Vector3d p(x, y, 1.1);
      const double e = (est * p - s.T_camL_sls * p).norm();
      ss += e * e, worst = std::max(worst, e), ++n;
    }
  const double rms = std::sqrt(ss / n);
  const Transform& points = run.fit.T_camL_sls_points;
  std::printf("second generator, the point fit alone: translation %.3f mm, rotation %.3f mrad\n",
              (points.translation() - s.T_camL_sls.translation()).norm() * 1e3,
              Eigen::AngleAxisd((s.T_camL_sls.inverse() * points).linear()).angle() * 1e3);
  std::printf(
      "second generator: fit RMS %.3f mm, hold-out %.3f mm (worst %.3f mm); against the truth: translation "
      "%.3f mm, rotation %.3f mrad, door grid (%d points) RMS %.3f mm, max %.3f mm\n",
      run.fit.rms_m * 1e3, run.fit.holdout_rms_m * 1e3, run.fit.holdout_max_m * 1e3, dt * 1e3, dr * 1e3, n,
      rms * 1e3, worst * 1e3);
  EXPECT_LT(dt, 0.5e-3);
  EXPECT_LT(rms, 0.5e-3);
  EXPECT_LT(run.fit.rms_m, 1e-3);
  EXPECT_GE(run.fit.corners_rms_px, 0.0);  // refined on the corners
  EXPECT_LT(run.fit.corners_rms_px, 0.5);
  EXPECT_GT(run.fit.holdout_rms_m, 0.0);
  EXPECT_LT(run.fit.holdout_rms_m, 1e-3);
  for (const ScannerCapture& c : run.captures) EXPECT_LT(c.match_rms_m, 0.5e-3) << c.name;

  // The daemon's loader reads what the command writes.
  ScannerCalibrationRun written = run;
  written.created_utc = "2026-12-06T00:00:00Z";
  written.tool_version = "test";
  write_scanner_calibration(tmp.path() / "scanner.yaml", written);
  const Transform loaded = station::load_transform(tmp.path() / "scanner.yaml", "T_camL_sls");
  EXPECT_LT((loaded.matrix() - est.matrix()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT(
      (load_scanner_calibration(tmp.path() / "scanner.yaml").matrix() - est.matrix()).cwiseAbs().maxCoeff(),
      1e-9);
}

TEST(ScannerCalibration, TooFewSpheresInTheScanIsNamed) {
  SecondScene s;
  ::dentmark::test::TempDir tmp("scanner-few");
  // The scan shows only two of the spheres (the others moved out of its reach).
  SecondScene scanned = s;
  scanned.target.spheres_board.resize(2);
  write_captures(scanned, tmp.path(), 1);
  try {
    calibrate_scanner_captures(tmp.path(), s.target, stereo_of(s), 0.001);
    FAIL() << "no error";
  } catch (const CalibrateError& e) {
    EXPECT_NE(std::string(e.what()).find("scan1.xyz: 2 of the target's 5 spheres found"), std::string::npos)
        << e.what();
  }
}

TEST(ScannerCalibration, AmbiguousOrBadTargetsAreRefused) {
  ::dentmark::test::TempDir tmp("scanner-target");
  ScannerTarget t = SecondScene().target;
  // A rectangle of spheres: its pairwise distances repeat.
  t.spheres_board = {{0, 0, 0.04}, {0.5, 0, 0.04}, {0.5, 0.3, 0.04}, {0, 0.3, 0.04}};
  write_scanner_target(tmp.path() / "t.yaml", t);
  EXPECT_THROW(
      {
        try {
          read_scanner_target(tmp.path() / "t.yaml");
        } catch (const CalibrateError& e) {
          EXPECT_NE(std::string(e.what()).find("t.yaml: field spheres_board: two sphere pairs"),
                    std::string::npos)
              << e.what();
          throw;
        }
      },
      CalibrateError);
  t = SecondScene().target;
  t.board = parse_target("chessboard:8x6", 0.05, 0, "");  // COLS + ROWS even: orientation unknown
  write_scanner_target(tmp.path() / "t2.yaml", t);
  EXPECT_THROW(read_scanner_target(tmp.path() / "t2.yaml"), CalibrateError);
  t = SecondScene().target;
  t.sphere_radius_m = 0.5;
  write_scanner_target(tmp.path() / "t3.yaml", t);
  EXPECT_THROW(read_scanner_target(tmp.path() / "t3.yaml"), CalibrateError);
}

TEST(ScannerCalibration, CapturesNeedAScanAndAPairEach) {
  ::dentmark::test::TempDir tmp("scanner-files");
  cv::Mat img(8, 8, CV_8U, cv::Scalar(0));
  cv::imwrite((tmp.path() / "left1.png").string(), img);
  cv::imwrite((tmp.path() / "right1.png").string(), img);
  std::ofstream(tmp.path() / "scan1.ply") << "ply\n";
  std::ofstream(tmp.path() / "scan2.xyz") << "0 0 0\n";
  try {
    find_scanner_captures(tmp.path());
    FAIL() << "no error";
  } catch (const CalibrateError& e) {
    EXPECT_NE(std::string(e.what()).find("scan2.xyz: no image pair left2/right2"), std::string::npos)
        << e.what();
  }
  std::filesystem::remove(tmp.path() / "scan2.xyz");
  EXPECT_EQ(find_scanner_captures(tmp.path()).size(), 1u);
}

}  // namespace
}  // namespace dentmark::calibrate
