#include "dentmark/firmware/track/panel_model.h"

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <string>

#include "dentmark/common/atomic_file.h"
#include "dentmark/common/yaml_file.h"
#include "dentmark/firmware/track/track_error.h"
#include "matrix_node.h"

namespace dentmark::track {
namespace {

constexpr int kFormatVersion = 1;
constexpr int kMaxFeatures = 256;

// The (2 half + 1)^2 patch on the grid around p at one level, or empty outside.
cv::Mat cut(const cv::Mat& level, const cv::Point2f& p, int half) {
  const cv::Point c(cvRound(p.x), cvRound(p.y));
  const cv::Rect r(c.x - half, c.y - half, 2 * half + 1, 2 * half + 1);
  if ((r & cv::Rect(0, 0, level.cols, level.rows)) != r) return {};
  return level(r).clone();
}

int read_int(const cv::FileStorage& fs, const std::string& file, const char* name, int lo, int hi) {
  const cv::FileNode node = fs[name];
  if (node.empty() || node.isNone()) throw TrackError(file + ": field " + name + " is missing");
  if (!(node.isInt() || node.isReal())) throw TrackError(file + ": field " + name + " is not a number");
  const double v = node.real();
  if (!(v >= lo && v <= hi) || v != std::floor(v))
    throw TrackError(file + ": field " + name + " must be an integer in [" + std::to_string(lo) + ", " +
                     std::to_string(hi) + "]");
  return static_cast<int>(v);
}

cv::Mat read_matrix(const cv::FileNode& node, const std::string& file, const std::string& name, int rows,
                    int cols) {
  if (node.empty() || node.isNone()) throw TrackError(file + ": field " + name + " is missing");
  detail::check_matrix_node(node, file, name, static_cast<double>(rows) * cols);
  cv::Mat m;
  try {
    node >> m;
  } catch (const cv::Exception&) {
    throw TrackError(file + ": field " + name + " is not an OpenCV matrix");
  }
  if (m.channels() != 1) m = m.reshape(1);
  if (m.rows != rows || m.cols != cols)
    throw TrackError(file + ": field " + name + " must be " + std::to_string(rows) + " x " +
                     std::to_string(cols));
  return m;
}

}  // namespace

std::vector<cv::Mat> model_pyramid(const cv::Mat& grey, int levels) {
  std::vector<cv::Mat> p{grey};
  for (int l = 1; l < levels; ++l) {
    cv::Mat down;
    cv::pyrDown(p.back(), down);
    p.push_back(down);
  }
  return p;
}

PanelModel make_panel_model(const cv::Mat& left, const cv::Mat& right,
                            const std::vector<Eigen::Vector3d>& p_camL,
                            const std::vector<cv::Point2f>& pixels_left,
                            const std::vector<cv::Point2f>& pixels_right, int levels, int template_half) {
  PanelModel model;
  model.image_size = left.size();
  model.levels = levels;
  model.template_half = template_half;
  const auto pl = model_pyramid(left, levels), pr = model_pyramid(right, levels);
  for (std::size_t i = 0; i < p_camL.size(); ++i) {
    ModelFeature f;
    f.p_camL = p_camL[i];
    f.pixel_left = pixels_left[i];
    f.pixel_right = pixels_right[i];
    bool inside = true;
    for (int l = 0; l < levels && inside; ++l) {
      const float s = 1.0f / static_cast<float>(1 << l);
      f.left.push_back(cut(pl[static_cast<std::size_t>(l)], pixels_left[i] * s, template_half));
      f.right.push_back(cut(pr[static_cast<std::size_t>(l)], pixels_right[i] * s, template_half));
      inside = !f.left.back().empty() && !f.right.back().empty();
    }
    if (inside) model.features.push_back(std::move(f));
  }
  if (model.features.size() < 3)
    throw TrackError("only " + std::to_string(model.features.size()) +
                     " features lie far enough inside both images for the model's templates (need 3)");
  return model;
}

void save_panel_model(const PanelModel& model, const std::filesystem::path& path) {
  const std::string file = path.string();
  try {
    // In memory, then written atomically: a crash never leaves half a model.
    cv::FileStorage fs(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
    if (!fs.isOpened()) throw TrackError(file + ": cannot write");
    const int n = static_cast<int>(model.features.size());
    cv::Mat layout(n, 3, CV_64F), px_l(n, 2, CV_64F), px_r(n, 2, CV_64F);
    for (int i = 0; i < n; ++i) {
      const ModelFeature& f = model.features[static_cast<std::size_t>(i)];
      for (int k = 0; k < 3; ++k) layout.at<double>(i, k) = f.p_camL(k);
      px_l.at<double>(i, 0) = f.pixel_left.x, px_l.at<double>(i, 1) = f.pixel_left.y;
      px_r.at<double>(i, 0) = f.pixel_right.x, px_r.at<double>(i, 1) = f.pixel_right.y;
    }
    fs << "dentmark_panel_model" << kFormatVersion;
    fs << "image_width" << model.image_size.width << "image_height" << model.image_size.height;
    fs << "levels" << model.levels << "template_half" << model.template_half;
    fs << "layout_camL" << layout << "pixels_left" << px_l << "pixels_right" << px_r;
    fs << "templates"
       << "[";
    for (const ModelFeature& f : model.features) {
      fs << "{"
         << "left"
         << "[";
      for (const cv::Mat& m : f.left) fs << m;
      fs << "]"
         << "right"
         << "[";
      for (const cv::Mat& m : f.right) fs << m;
      fs << "]"
         << "}";
    }
    fs << "]";
    files::write_atomically(path, fs.releaseAndGetString());
  } catch (const cv::Exception& e) {
    throw TrackError(file + ": cannot write (" + e.err + ")");
  } catch (const files::FileError& e) {
    throw TrackError(e.what());
  }
}

PanelModel load_panel_model(const std::filesystem::path& path, cv::Size expected) {
  const std::string file = path.string();
  cv::FileStorage fs = files::open_yaml_or_throw<TrackError>(path);
  if (read_int(fs, file, "dentmark_panel_model", 0, 1000) != kFormatVersion)
    throw TrackError(file + ": field dentmark_panel_model: unsupported version (this build reads " +
                     std::to_string(kFormatVersion) + ")");
  PanelModel m;
  m.image_size = {read_int(fs, file, "image_width", 16, 65535),
                  read_int(fs, file, "image_height", 16, 65535)};
  if (!expected.empty() && m.image_size != expected) {
    const char* field = m.image_size.width != expected.width ? "image_width" : "image_height";
    throw TrackError(file + ": field " + field + ": the model was taught on " +
                     std::to_string(m.image_size.width) + "x" + std::to_string(m.image_size.height) +
                     " images, these are " + std::to_string(expected.width) + "x" +
                     std::to_string(expected.height));
  }
  m.levels = read_int(fs, file, "levels", 1, 6);
  m.template_half = read_int(fs, file, "template_half", 2, 64);
  const cv::FileNode layout_node = fs["layout_camL"];
  if (layout_node.empty() || layout_node.isNone()) throw TrackError(file + ": field layout_camL is missing");
  const int n =
      layout_node.isMap() && layout_node["rows"].isInt() ? static_cast<int>(layout_node["rows"]) : -1;
  if (n < 3 || n > kMaxFeatures)
    throw TrackError(
        file + ": field layout_camL must be an N x 3 matrix with 3 <= N <= " + std::to_string(kMaxFeatures));
  cv::Mat layout, px_l, px_r;
  read_matrix(layout_node, file, "layout_camL", n, 3).convertTo(layout, CV_64F);
  read_matrix(fs["pixels_left"], file, "pixels_left", n, 2).convertTo(px_l, CV_64F);
  read_matrix(fs["pixels_right"], file, "pixels_right", n, 2).convertTo(px_r, CV_64F);
  if (!cv::checkRange(layout) || !cv::checkRange(px_l) || !cv::checkRange(px_r))
    throw TrackError(file + ": field layout_camL or pixels_* has a non-finite value");
  const cv::FileNode templates = fs["templates"];
  if (templates.empty() || templates.isNone()) throw TrackError(file + ": field templates is missing");
  if (!templates.isSeq() || static_cast<int>(templates.size()) != n)
    throw TrackError(file + ": field templates must list one entry per row of layout_camL (" +
                     std::to_string(n) + ")");
  const int side = 2 * m.template_half + 1;
  for (int i = 0; i < n; ++i) {
    ModelFeature f;
    for (int k = 0; k < 3; ++k) f.p_camL(k) = layout.at<double>(i, k);
    if (!(f.p_camL.z() > 0.0))
      throw TrackError(file + ": field layout_camL row " + std::to_string(i) + " is not in front of camL");
    f.pixel_left = {static_cast<float>(px_l.at<double>(i, 0)), static_cast<float>(px_l.at<double>(i, 1))};
    f.pixel_right = {static_cast<float>(px_r.at<double>(i, 0)), static_cast<float>(px_r.at<double>(i, 1))};
    const cv::FileNode t = templates[i];
    for (const char* cam : {"left", "right"}) {
      const std::string name = "templates[" + std::to_string(i) + "]." + cam;
      const cv::FileNode seq = t.isMap() ? t[cam] : cv::FileNode();
      if (seq.empty() || !seq.isSeq() || static_cast<int>(seq.size()) != m.levels)
        throw TrackError(file + ": field " + name + " must list " + std::to_string(m.levels) + " patches");
      for (int l = 0; l < m.levels; ++l) {
        cv::Mat patch = read_matrix(seq[l], file, name + "[" + std::to_string(l) + "]", side, side);
        if (patch.depth() != CV_8U) patch.convertTo(patch, CV_8U);
        (std::string(cam) == "left" ? f.left : f.right).push_back(patch);
      }
    }
    m.features.push_back(std::move(f));
  }
  return m;
}

}  // namespace dentmark::track
