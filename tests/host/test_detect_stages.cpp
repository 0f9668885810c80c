// The detection stages on hand-built height maps with known answers: detection scales,
// a candidate's shape and the design rules, the surroundings of design features, patch
// normals, the border zone and the final order (and merging) of findings.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "../../host/detect/border_zone.h"
#include "../../host/detect/design_rules.h"
#include "../../host/detect/deviation.h"
#include "../../host/detect/findings.h"
#include "../../host/detect/patch_normal.h"

namespace dentmark::detect {
namespace {

// A map of cols x rows pixels whose pixel (r, c) holds the surface point
// w = height(u, v) at its centre, weight weight(r, c) (0: no surface).
HeightMap make_map(int cols, int rows, double pixel, const std::function<double(double, double)>& height,
                   const std::function<float(int, int)>& weight) {
  HeightMap m;
  m.pixel = pixel;
  m.cols = cols, m.rows = rows;
  m.u0 = -0.013, m.v0 = 0.021;
  const std::size_t n = m.size();
  m.weight.assign(n, 0.0f), m.u.assign(n, 0.0f), m.v.assign(n, 0.0f), m.w.assign(n, 0.0f);
  m.cos_tilt.assign(n, 0.0f);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const std::size_t k = static_cast<std::size_t>(r) * cols + c;
      const float wt = weight(r, c);
      if (!(wt > 0.0f)) continue;
      const double u = m.u0 + (c + 0.5) * pixel, v = m.v0 + (r + 0.5) * pixel;
      m.weight[k] = wt;
      m.u[k] = static_cast<float>(u), m.v[k] = static_cast<float>(v);
      m.w[k] = static_cast<float>(height(u, v));
      m.cos_tilt[k] = 1.0f;
    }
  return m;
}

HeightMap flat_map(int cols, int rows, double pixel) {
  return make_map(
      cols, rows, pixel, [](double, double) { return 0.0; }, [](int, int) { return 1.0f; });
}

std::vector<std::int32_t> rect_pixels(int cols, int r0, int c0, int h, int w) {
  std::vector<std::int32_t> px;
  for (int r = r0; r < r0 + h; ++r)
    for (int c = c0; c < c0 + w; ++c) px.push_back(r * cols + c);
  return px;
}

double angle(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

// ---- detection_scales -----------------------------------------------------------------

TEST(DetectionScales, BoxSidesOf3And7And15MmInOddPixels) {
  EXPECT_EQ(detection_scales(0.001), (std::vector<int>{3, 7, 15}));
  // 6, 14 and 30 pixels: each raised to the next odd number.
  EXPECT_EQ(detection_scales(0.0005), (std::vector<int>{7, 15, 31}));
  // 1.5, 3.5, 7.5 rounded away from zero (2, 4, 8), then made odd.
  EXPECT_EQ(detection_scales(0.002), (std::vector<int>{3, 5, 9}));
}

TEST(DetectionScales, CoarsePixelsCollapseToDistinctOddSides) {
  // 0.33, 0.78 and 1.67 pixels: at least one pixel, 1 twice (kept once), 2 -> 3.
  EXPECT_EQ(detection_scales(0.009), (std::vector<int>{1, 3}));
  EXPECT_EQ(detection_scales(0.004), (std::vector<int>{1, 3, 5}));
  EXPECT_EQ(detection_scales(0.03), (std::vector<int>{1}));
  for (double pixel = 0.0002; pixel < 0.05; pixel *= 1.07) {
    const std::vector<int> s = detection_scales(pixel);
    ASSERT_FALSE(s.empty());
    for (std::size_t i = 0; i < s.size(); ++i) {
      EXPECT_EQ(s[i] % 2, 1) << "pixel " << pixel;
      if (i > 0) {
        EXPECT_GT(s[i], s[i - 1]) << "pixel " << pixel;
      }
    }
  }
}

// ---- shape_of and design_reason -------------------------------------------------------

// Standard deviation of n consecutive integers (the discrete uniform distribution),
// as the population covariance in shape_of sees them: sqrt((n² - 1) / 12).
double sigma_of_run(int n) {
  return std::sqrt((n * n - 1.0) / 12.0);
}

TEST(ShapeOf, BarLengthAndWidthAreFourSigmaPlusOnePixel) {
  const double h = 0.001;
  HeightMap map = flat_map(60, 40, h);
  // Uneven weights: the area is their sum times the pixel's area, not the pixel count.
  double weight_sum = 0.0;
  const std::vector<std::int32_t> bar = rect_pixels(map.cols, 10, 12, 4, 30);  // 4 rows, 30 cols
  for (std::size_t i = 0; i < bar.size(); ++i) {
    map.weight[static_cast<std::size_t>(bar[i])] = 0.5f + 0.25f * static_cast<float>(i % 4);
    weight_sum += map.weight[static_cast<std::size_t>(bar[i])];
  }
  const cv::Mat no_zone(map.rows, map.cols, CV_8U, cv::Scalar(0));
  const CandidateShape s = shape_of(bar, map, no_zone);
  EXPECT_NEAR(s.mean.x(), 12 + 14.5, 1e-9);  // column
  EXPECT_NEAR(s.mean.y(), 10 + 1.5, 1e-9);   // row
  EXPECT_NEAR(s.length, (4.0 * sigma_of_run(30) + 1.0) * h, 1e-9);
  EXPECT_NEAR(s.width, (4.0 * sigma_of_run(4) + 1.0) * h, 1e-9);
  // Close to the continuous uniform's n / sqrt(12) too.
  EXPECT_NEAR(s.length, (4.0 * 30 / std::sqrt(12.0) + 1.0) * h, 0.05 * h);
  EXPECT_NEAR(s.area, weight_sum * h * h, 1e-12);
  EXPECT_FALSE(s.touches_edge);

  // The same bar upright: length and width do not depend on the direction.
  const std::vector<std::int32_t> upright = rect_pixels(map.cols, 5, 40, 30, 4);
  const CandidateShape u = shape_of(upright, map, no_zone);
  EXPECT_NEAR(u.length, s.length, 1e-9);
  EXPECT_NEAR(u.width, s.width, 1e-9);
}

TEST(ShapeOf, TouchesEdgeOnlyWhenAPixelIsInTheBorderZone) {
  const HeightMap map = flat_map(60, 40, 0.001);
  const std::vector<std::int32_t> bar = rect_pixels(map.cols, 10, 12, 4, 30);
  cv::Mat zone(map.rows, map.cols, CV_8U, cv::Scalar(0));
  // Zone right next to the bar (column 42, row 10; and row 14 under it): not touching.
  zone.at<std::uint8_t>(10, 42) = 255;
  zone.at<std::uint8_t>(14, 20) = 255;
  EXPECT_FALSE(shape_of(bar, map, zone).touches_edge);
  // One pixel of the bar (its last column) in the zone.
  zone.at<std::uint8_t>(13, 41) = 255;
  EXPECT_TRUE(shape_of(bar, map, zone).touches_edge);
}

CandidateShape shape(double length, double width, bool edge = false) {
  CandidateShape s;
  s.length = length, s.width = width, s.touches_edge = edge;
  return s;
}

TEST(DesignReason, LongThinIsACharacterLineLargeIsAHandleRoundIsNone) {
  const DetectConfig cfg;
  ASSERT_DOUBLE_EQ(cfg.max_defect_diameter, 0.08);
  ASSERT_DOUBLE_EQ(cfg.max_elongation, 4.0);
  const auto reason = [&](const CandidateShape& s) {
    const char* why = design_reason(s, cfg);
    return why ? std::string(why) : std::string();
  };
  // Long (> 25 mm) and thin (elongation 8 > 4): a character line.
  EXPECT_NE(reason(shape(0.040, 0.005)).find("character line"), std::string::npos);
  // Longer than any defect, whatever its elongation.
  EXPECT_NE(reason(shape(0.090, 0.060)).find("handle"), std::string::npos);
  EXPECT_NE(reason(shape(0.090, 0.005)).find("handle"), std::string::npos);
  // Round 10 mm blob, a thin one under 25 mm, a long one not thin enough: defects.
  EXPECT_EQ(design_reason(shape(0.010, 0.010), cfg), nullptr);
  EXPECT_EQ(design_reason(shape(0.020, 0.002), cfg), nullptr);
  EXPECT_EQ(design_reason(shape(0.040, 0.011), cfg), nullptr);
  EXPECT_EQ(design_reason(shape(0.079, 0.060), cfg), nullptr);
  // Touching a border or opening: design, however round and small.
  EXPECT_NE(reason(shape(0.010, 0.010, true)).find("border"), std::string::npos);
  // The limits come from the configuration.
  DetectConfig loose = cfg;
  loose.max_elongation = 10.0;
  loose.max_defect_diameter = 0.1;
  EXPECT_EQ(design_reason(shape(0.040, 0.005), loose), nullptr);
  EXPECT_EQ(design_reason(shape(0.090, 0.060), loose), nullptr);
}

TEST(DesignReason, MeasuredBarsAndBlobs) {
  const HeightMap map = flat_map(60, 40, 0.001);
  const cv::Mat no_zone(map.rows, map.cols, CV_8U, cv::Scalar(0));
  const DetectConfig cfg;
  // 30 x 4 mm bar: 35.6 x 5.5 mm measured, a character line.
  const CandidateShape bar = shape_of(rect_pixels(map.cols, 10, 12, 4, 30), map, no_zone);
  ASSERT_NE(design_reason(bar, cfg), nullptr);
  EXPECT_NE(std::string(design_reason(bar, cfg)).find("character line"), std::string::npos);
  // A round blob of 10 mm diameter: not design.
  std::vector<std::int32_t> blob;
  for (int r = 0; r < map.rows; ++r)
    for (int c = 0; c < map.cols; ++c)
      if (std::hypot(r - 20.0, c - 30.0) <= 5.0) blob.push_back(r * map.cols + c);
  const CandidateShape round = shape_of(blob, map, no_zone);
  EXPECT_NEAR(round.length, round.width, 1e-9);
  EXPECT_NEAR(round.length, 0.011, 0.0015);  // a disc of radius R: 4 sigma = 2R, plus a pixel
  EXPECT_EQ(design_reason(round, cfg), nullptr);
}

// ---- design_surroundings and next_to_design -------------------------------------------

TEST(DesignSurroundings, EightMillimetresAroundTheDesign) {
  const double h = 0.001;
  cv::Mat design(60, 60, CV_8U, cv::Scalar(0));
  design.at<std::uint8_t>(30, 30) = 255;
  const cv::Mat s = design_surroundings(design, h);
  EXPECT_EQ(s.type(), CV_8U);
  EXPECT_EQ(s.at<std::uint8_t>(30, 30), 255);
  EXPECT_EQ(s.at<std::uint8_t>(30, 38), 255);  // 8 mm
  EXPECT_EQ(s.at<std::uint8_t>(22, 30), 255);
  EXPECT_EQ(s.at<std::uint8_t>(30, 39), 0);  // 9 mm
  EXPECT_EQ(s.at<std::uint8_t>(30, 41), 0);
  EXPECT_EQ(s.at<std::uint8_t>(37, 37), 0);  // 9.9 mm on the diagonal
  // Coarse pixels: at least 2 pixels.
  const cv::Mat coarse = design_surroundings(design, 0.01);
  EXPECT_EQ(coarse.at<std::uint8_t>(30, 32), 255);
  EXPECT_EQ(coarse.at<std::uint8_t>(30, 33), 0);
}

TEST(DesignSurroundings, ABordersBandTwoMillimetresTheRestEight) {
  // 1 mm pixels; the border zone is the left 3 columns; a border's candidate runs along
  // it (columns 3-8) and, as a crease would, out along row 50 to column 110.
  const double h = 0.001;
  cv::Mat design(100, 120, CV_8U, cv::Scalar(0)), border(100, 120, CV_8U, cv::Scalar(0)),
      zone(100, 120, CV_8U, cv::Scalar(0));
  zone.colRange(0, 3).setTo(255);
  border.colRange(3, 9).setTo(255);
  border.row(50).colRange(3, 111).setTo(255);
  const cv::Mat s = design_surroundings(design, border, zone, h);
  // Beside the band: 2 mm (columns 9, 10), not 3.
  EXPECT_EQ(s.at<std::uint8_t>(20, 10), 255);
  EXPECT_EQ(s.at<std::uint8_t>(20, 11), 0);
  EXPECT_EQ(s.at<std::uint8_t>(20, 16), 0);
  // The crease within 25 mm of the zone is the band's too (2 mm); beyond, its own 8 mm.
  EXPECT_EQ(s.at<std::uint8_t>(53, 20), 0);
  EXPECT_EQ(s.at<std::uint8_t>(58, 60), 255);
  EXPECT_EQ(s.at<std::uint8_t>(59, 60), 0);
  // Other design features: 8 mm as before.
  design.at<std::uint8_t>(20, 80) = 255;
  const cv::Mat t = design_surroundings(design, border, zone, h);
  EXPECT_EQ(t.at<std::uint8_t>(20, 88), 255);
  EXPECT_EQ(t.at<std::uint8_t>(20, 89), 0);
}

struct NextToDesign : ::testing::Test {
  static constexpr int kCols = 30, kRows = 20;
  cv::Mat surroundings{kRows, kCols, CV_8U, cv::Scalar(0)};
  cv::Mat deviation{kRows, kCols, CV_32F, cv::Scalar(0.0f)};
  // A 5 x 5 blob at rows 8..12, columns 10..14, deviation 0.1 mm but for its peak.
  std::vector<std::int32_t> blob = rect_pixels(kCols, 8, 10, 5, 5);
  void SetUp() override {
    for (auto k : blob) deviation.at<float>(k / kCols, k % kCols) = -1e-4f;
  }
  void surround_columns(int c0, int c1) {
    for (int r = 0; r < kRows; ++r)
      for (int c = c0; c <= c1; ++c) surroundings.at<std::uint8_t>(r, c) = 255;
  }
};

TEST_F(NextToDesign, PeakInsideTheSurroundingsCounts) {
  surround_columns(14, 29);              // only the blob's last column (5 of 25 pixels)
  deviation.at<float>(10, 14) = -4e-4f;  // the peak (a dent: by magnitude) there
  EXPECT_TRUE(next_to_design(blob, surroundings, deviation));
}

TEST_F(NextToDesign, EdgeInsidePeakOutsideDoesNot) {
  surround_columns(14, 29);
  deviation.at<float>(10, 11) = -4e-4f;  // the peak outside
  EXPECT_FALSE(next_to_design(blob, surroundings, deviation));
  // A positive peak larger than every dent pixel also outside: still not.
  deviation.at<float>(10, 12) = 5e-4f;
  EXPECT_FALSE(next_to_design(blob, surroundings, deviation));
  // The peak by magnitude moved inside: now it does.
  deviation.at<float>(9, 14) = -6e-4f;
  EXPECT_TRUE(next_to_design(blob, surroundings, deviation));
}

TEST_F(NextToDesign, MostPixelsInsideCountsHalfDoesNot) {
  deviation.at<float>(10, 10) = -4e-4f;  // peak in the first column, never surrounded
  surround_columns(12, 29);              // 15 of 25 pixels
  EXPECT_TRUE(next_to_design(blob, surroundings, deviation));
  // Exactly half (2 of a 4-pixel blob) is not most.
  const std::vector<std::int32_t> four = rect_pixels(kCols, 8, 10, 2, 2);  // columns 10, 11
  cv::Mat half(kRows, kCols, CV_8U, cv::Scalar(0));
  half.at<std::uint8_t>(8, 11) = half.at<std::uint8_t>(9, 11) = 255;
  EXPECT_FALSE(next_to_design(four, half, deviation));
  half.at<std::uint8_t>(9, 10) = 255;  // 3 of 4
  EXPECT_TRUE(next_to_design(four, half, deviation));
}

TEST_F(NextToDesign, FarFromDesignDoesNot) {
  surround_columns(20, 29);
  EXPECT_FALSE(next_to_design(blob, surroundings, deviation));
}

// ---- patch_normal ---------------------------------------------------------------------

constexpr double kA = 0.12, kB = -0.07;  // plane w = a u + b v

HeightMap tilted_plane(int n, double pixel) {
  return make_map(
      n, n, pixel, [](double u, double v) { return kA * u + kB * v; }, [](int, int) { return 1.0f; });
}

const Eigen::Vector3d kPlaneNormal = Eigen::Vector3d(-kA, -kB, 1.0).normalized();

TEST(PatchNormal, TiltedPlaneGivesItsNormalTowardsTheSensor) {
  const HeightMap map = tilted_plane(41, 0.001);
  const cv::Mat none(map.rows, map.cols, CV_8U, cv::Scalar(0));
  const Eigen::Vector3d n = patch_normal(map, 0.03, 20, 20, none);
  EXPECT_NEAR((n - kPlaneNormal).norm(), 0.0, 1e-6) << n.transpose();
  EXPECT_NEAR(n.norm(), 1.0, 1e-12);
  // Near the map's corner the patch is cut short; still the same plane.
  EXPECT_NEAR((patch_normal(map, 0.03, 0, 40, none) - kPlaneNormal).norm(), 0.0, 1e-6);
  // Turned over (w = -(a u + b v)): still oriented to +w.
  const HeightMap flipped = make_map(
      41, 41, 0.001, [](double u, double v) { return -(kA * u + kB * v); }, [](int, int) { return 1.0f; });
  const Eigen::Vector3d nf = patch_normal(flipped, 0.03, 20, 20, none);
  EXPECT_NEAR((nf - Eigen::Vector3d(kA, kB, 1.0).normalized()).norm(), 0.0, 1e-6) << nf.transpose();
}

TEST(PatchNormal, InScanFrameThroughTheMapAxes) {
  HeightMap map = tilted_plane(41, 0.001);
  const Eigen::Matrix3d rot =
      (Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()) * Eigen::AngleAxisd(-0.9, Eigen::Vector3d::UnitZ()))
          .toRotationMatrix();
  map.axes = rot.transpose();  // rows: u, v, w in the scan frame
  map.origin = Eigen::Vector3d(0.3, -0.2, 0.5);
  const cv::Mat none(map.rows, map.cols, CV_8U, cv::Scalar(0));
  const Eigen::Vector3d n = patch_normal(map, 0.03, 20, 20, none);
  EXPECT_NEAR((n - map.axes.transpose() * kPlaneNormal).norm(), 0.0, 1e-6) << n.transpose();
}

TEST(PatchNormal, ExcludedBumpLeavesItUnchanged) {
  HeightMap map = tilted_plane(41, 0.001);
  cv::Mat exclude(map.rows, map.cols, CV_8U, cv::Scalar(0));
  // A 5 mm bump off the patch's centre (rows 22..26, columns 23..27).
  for (int r = 22; r <= 26; ++r)
    for (int c = 23; c <= 27; ++c) {
      map.w[static_cast<std::size_t>(r * map.cols + c)] += 0.005f;
      exclude.at<std::uint8_t>(r, c) = 255;
    }
  EXPECT_NEAR((patch_normal(map, 0.03, 20, 20, exclude) - kPlaneNormal).norm(), 0.0, 1e-6);
  const cv::Mat none(map.rows, map.cols, CV_8U, cv::Scalar(0));
  EXPECT_GT(angle(patch_normal(map, 0.03, 20, 20, none), kPlaneNormal), 1e-3);
}

TEST(PatchNormal, OnlyThePatchCounts) {
  // 30 mm patch at 1 mm: 15 pixels each way of the centre, no more.
  HeightMap map = tilted_plane(41, 0.001);
  const cv::Mat none(map.rows, map.cols, CV_8U, cv::Scalar(0));
  for (int r = 0; r < map.rows; ++r) map.w[static_cast<std::size_t>(r * map.cols + 36)] += 0.01f;
  EXPECT_NEAR((patch_normal(map, 0.03, 20, 20, none) - kPlaneNormal).norm(), 0.0, 1e-6);
  for (int r = 0; r < map.rows; ++r) map.w[static_cast<std::size_t>(r * map.cols + 35)] += 0.01f;
  EXPECT_GT(angle(patch_normal(map, 0.03, 20, 20, none), kPlaneNormal), 1e-3);
  // Empty pixels (weight 0) do not count either, whatever their w.
  HeightMap holes = tilted_plane(41, 0.001);
  for (int r = 20; r <= 30; ++r) {
    const std::size_t k = static_cast<std::size_t>(r * holes.cols + 25);
    holes.weight[k] = 0.0f, holes.w[k] = 0.05f;
  }
  EXPECT_NEAR((patch_normal(holes, 0.03, 20, 20, none) - kPlaneNormal).norm(), 0.0, 1e-6);
}

TEST(PatchNormal, TooFewOrCollinearPixelsGiveTheWAxis) {
  HeightMap map = tilted_plane(41, 0.001);
  map.axes = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1.0, 2.0, 0.5).normalized()).toRotationMatrix();
  const Eigen::Vector3d w_axis = map.axes.row(2).transpose();
  cv::Mat exclude(map.rows, map.cols, CV_8U, cv::Scalar(255));
  exclude.at<std::uint8_t>(20, 20) = exclude.at<std::uint8_t>(21, 25) = 0;  // two pixels left
  EXPECT_NEAR((patch_normal(map, 0.03, 20, 20, exclude) - w_axis).norm(), 0.0, 1e-12);
  exclude.at<std::uint8_t>(12, 17) = 0;  // a third: a plane again, not the w axis
  EXPECT_NEAR((patch_normal(map, 0.03, 20, 20, exclude) - map.axes.transpose() * kPlaneNormal).norm(), 0.0,
              1e-5);
  // Pixels along one row of a tilted plane lie on a line: no plane.
  cv::Mat row_only(map.rows, map.cols, CV_8U, cv::Scalar(255));
  for (int c = 0; c < map.cols; ++c) row_only.at<std::uint8_t>(20, c) = 0;
  EXPECT_NEAR((patch_normal(map, 0.03, 20, 20, row_only) - w_axis).norm(), 0.0, 1e-12);
}

// ---- border_zone ----------------------------------------------------------------------

// 100 x 80 mm at 1 mm: an empty one-pixel ring round the map (as build_height_map
// leaves it), an empty 20 x 20 mm window at rows 30..49, columns 40..59, surface elsewhere.
bool in_window(int r, int c) {
  return r >= 30 && r < 50 && c >= 40 && c < 60;
}

HeightMap windowed_map(const std::function<bool(int, int)>& empty) {
  return make_map(
      100, 80, 0.001, [](double, double) { return 0.0; },
      [&](int r, int c) { return r == 0 || c == 0 || r == 79 || c == 99 || empty(r, c) ? 0.0f : 1.0f; });
}

TEST(BorderZone, ThreeMillimetresRoundTheWindowAndTheMapBorder) {
  const HeightMap map = windowed_map(in_window);
  const cv::Mat z = border_zone(map);
  ASSERT_EQ(z.type(), CV_8U);
  ASSERT_EQ(z.rows, map.rows);
  ASSERT_EQ(z.cols, map.cols);
  const auto in = [&](int r, int c) { return z.at<std::uint8_t>(r, c) != 0; };
  // Left of the window (its first column 40), right (last 59), above (30), below (49).
  for (int r : {30, 40, 49}) {
    EXPECT_TRUE(in(r, 39)) << r;
    EXPECT_TRUE(in(r, 37)) << r;   // 3 mm
    EXPECT_FALSE(in(r, 36)) << r;  // 4 mm
    EXPECT_FALSE(in(r, 35)) << r;  // 5 mm
    EXPECT_TRUE(in(r, 62)) << r;
    EXPECT_FALSE(in(r, 64)) << r;
  }
  for (int c : {40, 50, 59}) {
    EXPECT_TRUE(in(27, c)) << c;
    EXPECT_FALSE(in(26, c)) << c;
    EXPECT_FALSE(in(25, c)) << c;
    EXPECT_TRUE(in(52, c)) << c;
    EXPECT_FALSE(in(54, c)) << c;
  }
  struct Probe {
    int r, c;
    bool in;
    const char* what;
  };
  for (const Probe& p :
       {Probe{40, 1, true, "next to the map's empty ring (row/column 0 and 79/99)"},
        Probe{40, 3, true, "3 mm from the ring"}, Probe{40, 4, false, "4 mm from the ring"},
        Probe{40, 5, false, "5 mm from the ring"}, Probe{76, 20, true, "3 mm from the bottom ring"},
        Probe{74, 20, false, "5 mm from the bottom ring"}, Probe{1, 1, true, "in the corner"},
        Probe{40, 50, false, "inside the window: no surface"},
        Probe{30, 40, false, "inside the window: no surface"},
        Probe{0, 40, false, "on the empty ring: no surface"}, Probe{15, 20, false, "far from everything"},
        Probe{40, 80, false, "far from everything"}})
    EXPECT_EQ(in(p.r, p.c), p.in) << p.what << " (" << p.r << ", " << p.c << ")";
}

TEST(BorderZone, SmallDropoutIsNotOutsideALargeOneIs) {
  // A 3 x 3 mm dropout at rows 10..12, columns 10..12: no zone round it.
  const HeightMap small =
      windowed_map([](int r, int c) { return in_window(r, c) || (r >= 10 && r < 13 && c >= 10 && c < 13); });
  const cv::Mat zs = border_zone(small);
  for (int r = 6; r <= 16; ++r)
    for (int c = 6; c <= 16; ++c) EXPECT_EQ(zs.at<std::uint8_t>(r, c), 0) << r << ", " << c;
  // A 12 x 12 mm one (wider than 10 x 10 mm) at rows 10..21, columns 10..21 is outside.
  const HeightMap large =
      windowed_map([](int r, int c) { return in_window(r, c) || (r >= 10 && r < 22 && c >= 10 && c < 22); });
  const cv::Mat zl = border_zone(large);
  EXPECT_NE(zl.at<std::uint8_t>(15, 9), 0);
  EXPECT_NE(zl.at<std::uint8_t>(15, 7), 0);
  EXPECT_EQ(zl.at<std::uint8_t>(15, 5), 0);
  EXPECT_NE(zl.at<std::uint8_t>(24, 15), 0);
}

TEST(BorderZone, AtLeastTwoPixelsOnCoarseMaps) {
  // 5 mm pixels: 3 mm is less than a pixel; the zone is still two pixels wide.
  const HeightMap map = make_map(
      20, 20, 0.005, [](double, double) { return 0.0; },
      [](int r, int c) { return r == 0 || c == 0 || r == 19 || c == 19 ? 0.0f : 1.0f; });
  const cv::Mat z = border_zone(map);
  EXPECT_NE(z.at<std::uint8_t>(10, 1), 0);
  EXPECT_NE(z.at<std::uint8_t>(10, 2), 0);
  EXPECT_EQ(z.at<std::uint8_t>(10, 3), 0);
}

// ---- order_findings -------------------------------------------------------------------

Finding finding(std::uint32_t id, protocol::DefectClass cls, double score, const Eigen::Vector3d& position,
                double diameter) {
  Finding f;
  f.defect.id = id;
  f.defect.defect_class = cls;
  f.defect.score = score;
  f.defect.position = position;
  f.defect.diameter = diameter;
  f.reason = "entry " + std::to_string(id);
  return f;
}

constexpr auto kDent = protocol::DefectClass::kDent;
constexpr auto kBump = protocol::DefectClass::kBump;

TEST(OrderFindings, MostConfidentFirstIdsThenFeatures) {
  Detection d;
  // Far apart: no merging. Each entry's id is its index in labels.
  d.defects.push_back(finding(0, kDent, 0.4, {0.0, 0.0, 0.0}, 0.01));
  d.defects.push_back(finding(1, kBump, 0.9, {0.1, 0.0, 0.0}, 0.01));
  d.defects.push_back(finding(2, kDent, 0.2, {0.2, 0.0, 0.0}, 0.01));
  d.defects.push_back(finding(3, kDent, 0.7, {0.3, 0.0, 0.0}, 0.01));
  d.features.push_back(finding(0, protocol::DefectClass::kDesignFeature, 1.0, {0.0, 0.1, 0.0}, 0.05));
  d.features.push_back(finding(0, protocol::DefectClass::kNoise, 0.1, {0.0, 0.2, 0.0}, 0.01));
  d.labels = {-1, 0, 1, 2, 3, -2, -3, 3, 0};
  order_findings(d);
  ASSERT_EQ(d.defects.size(), 4u);
  const std::vector<std::string> order{"entry 1", "entry 3", "entry 0", "entry 2"};  // 0.9, 0.7, 0.4, 0.2
  for (std::size_t i = 0; i < order.size(); ++i) {
    EXPECT_EQ(d.defects[i].reason, order[i]);
    EXPECT_EQ(d.defects[i].defect.id, i + 1);
  }
  EXPECT_EQ(d.features[0].defect.id, 5u);
  EXPECT_EQ(d.features[1].defect.id, 6u);
  // Labels follow: old 0 -> 2, 1 -> 0, 2 -> 3, 3 -> 1; features and background untouched.
  EXPECT_EQ(d.labels, (std::vector<std::int32_t>{-1, 2, 0, 3, 1, -2, -3, 1, 2}));
}

TEST(OrderFindings, SplitDefectMergesIntoTheMoreConfidentOne) {
  Detection d;
  // Entries 0 and 2 are one dent (centres 4 mm apart, diameters 10 and 6 mm: inside
  // half the larger); entry 1 is a bump at the same place (another class: kept);
  // entry 3 a dent 6 mm from entry 2 (more than half of either diameter: kept).
  d.defects.push_back(finding(0, kDent, 0.5, {0.004, 0.0, 0.0}, 0.006));
  d.defects.push_back(finding(1, kBump, 0.6, {0.0, 0.0, 0.0}, 0.010));
  d.defects.push_back(finding(2, kDent, 0.8, {0.0, 0.0, 0.0}, 0.010));
  d.defects.push_back(finding(3, kDent, 0.3, {-0.006, 0.0, 0.0}, 0.010));
  d.features.push_back(finding(0, protocol::DefectClass::kNoise, 0.1, {0.0, 0.2, 0.0}, 0.01));
  d.labels = {0, 1, 2, 3, -1, -2, 0};
  order_findings(d);
  ASSERT_EQ(d.defects.size(), 3u);
  EXPECT_EQ(d.defects[0].reason, "entry 2");       // the dent, 0.8
  EXPECT_EQ(d.defects[1].reason, "entry 1");       // the bump, 0.6
  EXPECT_EQ(d.defects[2].reason, "entry 3");       // the other dent, 0.3
  EXPECT_EQ(d.defects[0].defect.diameter, 0.010);  // the kept one's own measurements
  for (std::size_t i = 0; i < d.defects.size(); ++i) EXPECT_EQ(d.defects[i].defect.id, i + 1);
  EXPECT_EQ(d.features[0].defect.id, 4u);
  // Entry 0's pixels now belong to entry 2's finding (index 0).
  EXPECT_EQ(d.labels, (std::vector<std::int32_t>{0, 1, 0, 2, -1, -2, 0}));
}

TEST(OrderFindings, LargerLessConfidentReportJoinsASmallerOne) {
  // Half the larger diameter counts: a 20 mm report 8 mm from a 4 mm one joins it; at
  // 10.5 mm it does not.
  const auto ordered = [](double apart) {
    Detection d;
    d.defects.push_back(finding(0, kBump, 0.3, {0.0, apart, 0.0}, 0.020));
    d.defects.push_back(finding(1, kBump, 0.9, {0.0, 0.0, 0.0}, 0.004));
    d.labels = {0, 1};
    order_findings(d);
    return d;
  };
  const Detection joined = ordered(0.008);
  ASSERT_EQ(joined.defects.size(), 1u);
  EXPECT_EQ(joined.defects[0].reason, "entry 1");
  EXPECT_EQ(joined.labels, (std::vector<std::int32_t>{0, 0}));
  const Detection apart = ordered(0.0105);
  ASSERT_EQ(apart.defects.size(), 2u);
  EXPECT_EQ(apart.labels, (std::vector<std::int32_t>{1, 0}));
}

}  // namespace
}  // namespace dentmark::detect
