#include "opencv_sample_data.h"

#include <cstdio>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace dentmark::calibrate::test {

namespace fs = std::filesystem;

namespace {
std::string name(const char* side, int n) {
  char b[32];
  std::snprintf(b, sizeof b, "%s%02d.jpg", side, n);
  return b;
}
}  // namespace

std::string opencv_data_problem() {
  for (int n : kOpenCvPairs)
    for (const char* side : {"left", "right"}) {
      const fs::path p = kOpenCvData / name(side, n);
      if (!fs::exists(p))
        return p.string() + " is missing" + (fs::exists(p.string() + ".gz") ? " (found .gz)" : "") +
               ": install opencv-doc (scripts/setup-deps)";
    }
  return {};
}

void copy_opencv_pairs(const fs::path& dir) {
  fs::create_directories(dir);
  for (int n : kOpenCvPairs)
    for (const char* side : {"left", "right"})
      fs::copy_file(kOpenCvData / name(side, n), dir / name(side, n), fs::copy_options::overwrite_existing);
}

SampleResult opencv_sample_stereo_calib(const std::vector<fs::path>& lefts,
                                        const std::vector<fs::path>& rights, double square_m) {
  const cv::Size board(9, 6);
  const int max_scale = 2;
  std::vector<std::vector<cv::Point2f>> image_points[2];
  cv::Size image_size;
  for (std::size_t i = 0; i < lefts.size(); ++i) {
    std::vector<cv::Point2f> corners[2];
    int k = 0;
    for (; k < 2; ++k) {
      const cv::Mat img = cv::imread((k == 0 ? lefts[i] : rights[i]).string(), cv::IMREAD_GRAYSCALE);
      if (img.empty()) break;
      if (image_size == cv::Size()) image_size = img.size();
      if (img.size() != image_size) break;
      bool found = false;
      for (int scale = 1; scale <= max_scale; ++scale) {
        cv::Mat timg;
        if (scale == 1)
          timg = img;
        else
          cv::resize(img, timg, cv::Size(), scale, scale, cv::INTER_LINEAR_EXACT);
        found = cv::findChessboardCorners(timg, board, corners[k],
                                          cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
        if (found) {
          if (scale > 1) {
            cv::Mat m(corners[k]);
            m *= 1. / scale;
          }
          break;
        }
      }
      if (!found) break;
      cv::cornerSubPix(img, corners[k], cv::Size(11, 11), cv::Size(-1, -1),
                       cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 30, 0.01));
    }
    if (k == 2) {
      image_points[0].push_back(corners[0]);
      image_points[1].push_back(corners[1]);
    }
  }
  SampleResult out;
  out.pairs = static_cast<int>(image_points[0].size());
  if (out.pairs < 2) return out;
  std::vector<std::vector<cv::Point3f>> object_points(image_points[0].size());
  for (auto& o : object_points)
    for (int j = 0; j < board.height; ++j)
      for (int k = 0; k < board.width; ++k)
        o.emplace_back(static_cast<float>(k * square_m), static_cast<float>(j * square_m), 0.0f);
  cv::Mat camera_matrix[2], dist_coeffs[2];
  camera_matrix[0] = cv::initCameraMatrix2D(object_points, image_points[0], image_size, 0);
  camera_matrix[1] = cv::initCameraMatrix2D(object_points, image_points[1], image_size, 0);
  cv::Mat r, t, e, f;
  out.rms_px = cv::stereoCalibrate(
      object_points, image_points[0], image_points[1], camera_matrix[0], dist_coeffs[0], camera_matrix[1],
      dist_coeffs[1], image_size, r, t, e, f,
      cv::CALIB_FIX_ASPECT_RATIO + cv::CALIB_ZERO_TANGENT_DIST + cv::CALIB_USE_INTRINSIC_GUESS +
          cv::CALIB_SAME_FOCAL_LENGTH + cv::CALIB_RATIONAL_MODEL + cv::CALIB_FIX_K3 + cv::CALIB_FIX_K4 +
          cv::CALIB_FIX_K5,
      cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-5));
  return out;
}

}  // namespace dentmark::calibrate::test
