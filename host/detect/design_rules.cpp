#include "design_rules.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <opencv2/imgproc.hpp>

#include "dilate.h"

namespace dentmark::detect {
namespace {

// A border's band: its design candidates' pixels within this distance of the border zone
// (m; a rolled edge's roll-off spread by the widest box mean reaches ~16 mm) ...
constexpr double kBorderBand = 0.025;
// ... and how far beyond it a candidate is next to it (m).
constexpr double kBesideBorder = 0.002;

}  // namespace

CandidateShape shape_of(const std::vector<std::int32_t>& pixels, const HeightMap& map,
                        const cv::Mat& border_zone) {
  const int cols = map.cols;
  const double h = map.pixel;
  CandidateShape sh;
  for (auto k : pixels) sh.mean += Eigen::Vector2d(k % cols, k / cols);
  sh.mean /= static_cast<double>(pixels.size());
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (auto k : pixels) {
    const Eigen::Vector2d d = Eigen::Vector2d(k % cols, k / cols) - sh.mean;
    cov += d * d.transpose();
    sh.touches_edge = sh.touches_edge || border_zone.data[k];
    sh.area += map.weight[static_cast<std::size_t>(k)] * h * h;
  }
  cov /= static_cast<double>(pixels.size());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
  sh.length = (4.0 * std::sqrt(std::max(0.0, eig.eigenvalues()(1))) + 1.0) * h;
  sh.width = (4.0 * std::sqrt(std::max(0.0, eig.eigenvalues()(0))) + 1.0) * h;
  return sh;
}

const char* design_reason(const CandidateShape& shape, const DetectConfig& cfg) {
  if (shape.touches_edge) return "touches a border or opening";
  if (shape.length > cfg.max_defect_diameter) return "larger than any defect (handle, panel shape)";
  if (shape.length > cfg.min_line_length && shape.length / shape.width > cfg.max_elongation)
    return "long and thin (character line)";
  return nullptr;
}

cv::Mat design_surroundings(const cv::Mat& design, double pixel) {
  const int rad = std::max(2, static_cast<int>(std::lround(0.008 / pixel)));
  cv::Mat out;
  dilate_in_strips(design, out, cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * rad + 1, 2 * rad + 1}));
  return out;
}

cv::Mat design_surroundings(const cv::Mat& design, const cv::Mat& border_design, const cv::Mat& edge_zone,
                            double pixel) {
  const int band = static_cast<int>(std::lround(kBorderBand / pixel));
  cv::Mat near_edge, near_band;
  dilate_in_strips(edge_zone, near_edge,
                   cv::getStructuringElement(cv::MORPH_RECT, {2 * band + 1, 2 * band + 1}));
  const int rad = std::max(1, static_cast<int>(std::lround(kBesideBorder / pixel)));
  dilate_in_strips(border_design & near_edge, near_band,
                   cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * rad + 1, 2 * rad + 1}));
  return design_surroundings(design | (border_design & ~near_edge), pixel) | near_band;
}

bool next_to_design(const std::vector<std::int32_t>& pixels, const cv::Mat& surroundings,
                    const cv::Mat& deviation) {
  const int cols = deviation.cols;
  std::ptrdiff_t near = 0;
  std::int32_t peak = pixels.front();
  float peak_dev = 0.0f;
  for (auto k : pixels) {
    near += surroundings.data[k] != 0;
    const float dv = std::abs(deviation.at<float>(k / cols, k % cols));
    if (dv > peak_dev) peak_dev = dv, peak = k;
  }
  return near > 0 && (2 * near > static_cast<std::ptrdiff_t>(pixels.size()) || surroundings.data[peak]);
}

}  // namespace dentmark::detect
