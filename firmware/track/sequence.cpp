#include "dentmark/firmware/track/sequence.h"

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "dentmark/common/image/png_io.h"
#include "dentmark/common/stereo_index.h"
#include "dentmark/common/yaml_file.h"
#include "dentmark/firmware/track/track_error.h"
#include "matrix_node.h"

namespace dentmark::track {
namespace fs = std::filesystem;

Sequence load_sequence(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw TrackError(dir.string() + ": not a directory");
  Sequence seq;
  seq.dir = dir;
  seq.calibration = load_stereo_calibration(dir / "stereo.yaml");

  try {
    for (files::StereoIndexEntry& e : files::read_stereo_index(dir))
      seq.frames.push_back({e.index, e.t, std::move(e.left), std::move(e.right)});
  } catch (const files::StereoIndexError& e) {
    throw TrackError(e.what());
  }
  return seq;
}

std::vector<cv::Point2f> load_seeds(const fs::path& path, cv::Size size) {
  const std::string file = path.string();
  cv::FileStorage fs = files::open_yaml_or_throw<TrackError>(path);
  const cv::FileNode node = fs["seeds_right"];
  if (node.empty() || node.isNone()) throw TrackError(file + ": field seeds_right is missing");
  detail::check_matrix_node(node, file, "seeds_right", 2 * 4096);
  cv::Mat m;
  try {
    node >> m;
  } catch (const cv::Exception&) {
    throw TrackError(file + ": field seeds_right is not an OpenCV matrix");
  }
  if (m.channels() == 2) m = m.reshape(1, static_cast<int>(m.total()));
  if (m.empty() || m.cols != 2) throw TrackError(file + ": field seeds_right must be an N x 2 matrix");
  cv::Mat d;
  m.convertTo(d, CV_64F);
  std::vector<cv::Point2f> seeds;
  for (int i = 0; i < d.rows; ++i) {
    const double x = d.at<double>(i, 0), y = d.at<double>(i, 1);
    if (!std::isfinite(x) || !std::isfinite(y) || x < 0 || y < 0 || x > size.width - 1 ||
        y > size.height - 1) {
      std::ostringstream os;
      os << file << ": seeds_right row " << i << " (" << x << ", " << y << ") is outside the " << size.width
         << "x" << size.height << " image";
      throw TrackError(os.str());
    }
    seeds.emplace_back(static_cast<float>(x), static_cast<float>(y));
  }
  return seeds;
}

cv::Mat load_grey(const fs::path& path, cv::Size expected) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw TrackError(path.string() + ": no such file");
  cv::Mat img;
  try {
    img = image::read_png(path.string());
  } catch (const image::ImageError& e) {
    throw TrackError(std::string(e.what()) + " (unreadable image)");
  }
  if (img.size() != expected) {
    std::ostringstream os;
    os << path.string() << ": image is " << img.cols << "x" << img.rows << ", stereo.yaml says "
       << expected.width << "x" << expected.height;
    throw TrackError(os.str());
  }
  if (img.depth() == CV_16U) img.convertTo(img, CV_8U, 1.0 / 256.0);
  if (img.depth() != CV_8U) throw TrackError(path.string() + ": unsupported pixel type (need 8 or 16 bit)");
  if (img.channels() == 3)
    cv::cvtColor(img, img, cv::COLOR_BGR2GRAY);
  else if (img.channels() != 1)
    throw TrackError(path.string() + ": unsupported channel count");
  return img;
}

}  // namespace dentmark::track
