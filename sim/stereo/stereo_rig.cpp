#include "dentmark/sim/stereo/stereo_rig.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "dentmark/sim/stereo/sequence_writer.h"

namespace dentmark::sim::stereo {

StereoRig make_rig(cv::Size size, double focal_px, double baseline_m, double toe_in_rad, double k1) {
  StereoRig rig;
  rig.size = size;
  // Principal points slightly off centre, as real calibrations have them.
  const cv::Matx33d k(focal_px, 0, 0.5 * size.width - 3.5, 0, focal_px, 0.5 * size.height + 2.25, 0, 0, 1);
  rig.left.K = k;
  rig.right.K = cv::Matx33d(focal_px * 1.002, 0, 0.5 * size.width + 4.0, 0, focal_px * 1.002,
                            0.5 * size.height - 1.5, 0, 0, 1);
  rig.left.D = cv::Mat::zeros(1, 5, CV_64F);
  rig.right.D = cv::Mat::zeros(1, 5, CV_64F);
  rig.left.D.at<double>(0) = k1;
  rig.right.D.at<double>(0) = k1;
  // camR at c = (baseline, 0, 0) in camL, turned about y so its axis leans towards camL's.
  const Eigen::Matrix3d r = Eigen::AngleAxisd(toe_in_rad, Eigen::Vector3d::UnitY()).toRotationMatrix();
  rig.T_camR_camL = Transform::Identity();
  rig.T_camR_camL.linear() = r;
  rig.T_camR_camL.translation() = -r * Eigen::Vector3d(baseline_m, 0.0, 0.0);
  return rig;
}

void write_stereo_yaml(const StereoRig& rig, const std::filesystem::path& path) {
  cv::FileStorage fs(path.string(), cv::FileStorage::WRITE);
  if (!fs.isOpened()) throw SequenceError(path.string() + ": cannot open for writing");
  cv::Mat r, t;
  const Eigen::Matrix3d rr = rig.T_camR_camL.linear();
  const Eigen::Vector3d tt = rig.T_camR_camL.translation();
  cv::eigen2cv(rr, r);
  cv::eigen2cv(tt, t);
  fs << "image_width" << rig.size.width << "image_height" << rig.size.height;
  fs << "K1" << cv::Mat(rig.left.K) << "D1" << rig.left.D << "K2" << cv::Mat(rig.right.K) << "D2"
     << rig.right.D;
  fs << "R" << r << "T" << t;
}

cv::Mat normalized_pixel_grid(const PinholeCamera& cam, cv::Size size) {
  std::vector<cv::Point2f> pix;
  pix.reserve(static_cast<std::size_t>(size.area()));
  for (int v = 0; v < size.height; ++v)
    for (int u = 0; u < size.width; ++u) pix.emplace_back(static_cast<float>(u), static_cast<float>(v));
  std::vector<cv::Point2f> norm;
  cv::undistortPoints(pix, norm, cam.K, cam.D);
  return cv::Mat(norm, true).reshape(2, size.height);
}

cv::Mat expose_8bit(cv::Mat1f image, double blur_sigma, double noise_sigma, cv::RNG& rng) {
  if (blur_sigma > 0.0) cv::GaussianBlur(image, image, cv::Size(0, 0), blur_sigma);
  if (noise_sigma > 0.0) {
    cv::Mat1f noise(image.size());
    rng.fill(noise, cv::RNG::NORMAL, 0.0, noise_sigma);
    image += noise;
  }
  cv::Mat out;
  image.convertTo(out, CV_8U);  // saturates
  return out;
}

}  // namespace dentmark::sim::stereo
