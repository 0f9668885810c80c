#pragma once
// A taught panel model (design.md §4, operator-free start): the macro-features' image
// templates at several pyramid levels in both cameras, and their 3D layout in camL at
// the teach frame (metres). `dentmark-edge teach` writes it; a later panel of the same
// model is then acquired without seeds (model_search.h). Stored as OpenCV FileStorage
// YAML:
//   dentmark_panel_model: 1
//   image_width, image_height   the cameras it was taught with, px
//   levels, template_half       pyramid levels 0..levels-1, patches (2 half + 1)^2 px
//   layout_camL                 N x 3, metres
//   pixels_left, pixels_right   N x 2, where the features were at the teach frame, px
//   templates                   N maps {left: [level 0, 1, ...], right: [...]}, 8-bit

#include <Eigen/Core>
#include <filesystem>
#include <opencv2/core.hpp>
#include <vector>

#include "dentmark/firmware/track/stereo_calibration.h"

namespace dentmark::track {

struct ModelFeature {
  Eigen::Vector3d p_camL = Eigen::Vector3d::Zero();  // at the teach frame, m
  cv::Point2f pixel_left, pixel_right;               // at the teach frame, px
  std::vector<cv::Mat> left, right;                  // CV_8U patches, one per pyramid level
};

struct PanelModel {
  cv::Size image_size;
  int levels = 3;
  int template_half = 10;
  std::vector<ModelFeature> features;
};

// Pyramid of an 8-bit grey image: level l is level l−1 halved by cv::pyrDown, so a
// level-0 pixel p sits at p / 2^l.
std::vector<cv::Mat> model_pyramid(const cv::Mat& grey, int levels);

// Cuts the model's patches around the features (camL points and their pixels in both
// images of one stereo frame). Features whose coarsest patch would leave the image are
// left out. Throws TrackError when fewer than 3 remain.
PanelModel make_panel_model(const cv::Mat& left, const cv::Mat& right,
                            const std::vector<Eigen::Vector3d>& p_camL,
                            const std::vector<cv::Point2f>& pixels_left,
                            const std::vector<cv::Point2f>& pixels_right, int levels = 3,
                            int template_half = 10);

// Writes the model (throws TrackError naming the file when it cannot).
void save_panel_model(const PanelModel& model, const std::filesystem::path& path);

// Reads and checks a model: a missing, unreadable or malformed file, or one taught at
// another image size than `expected_size` (when not empty), throws TrackError naming
// the file and the field.
PanelModel load_panel_model(const std::filesystem::path& path, cv::Size expected_size = {});

}  // namespace dentmark::track
