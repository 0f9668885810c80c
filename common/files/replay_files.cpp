#include "dentmark/common/replay_files.h"

#include <iomanip>
#include <opencv2/core.hpp>
#include <sstream>

#include "dentmark/common/atomic_file.h"
#include "dentmark/common/stereo_index.h"

namespace dentmark::files {
namespace fs = std::filesystem;

void write_replay_seeds(const fs::path& path, const std::vector<cv::Point2f>& seeds_right) {
  cv::Mat seeds(static_cast<int>(seeds_right.size()), 2, CV_32F);
  for (std::size_t i = 0; i < seeds_right.size(); ++i) {
    seeds.at<float>(static_cast<int>(i), 0) = seeds_right[i].x;
    seeds.at<float>(static_cast<int>(i), 1) = seeds_right[i].y;
  }
  try {
    cv::FileStorage sf(path.string(), cv::FileStorage::WRITE);
    if (!sf.isOpened()) throw FileError(path, "cannot open for writing");
    sf << "seeds_right" << seeds;
  } catch (const cv::Exception& e) {
    throw FileError(path, e.what());
  }
}

void write_replay_points(const fs::path& path, const std::vector<Eigen::Vector3d>& points) {
  std::ofstream f(path);
  f << "x,y,z\n" << std::setprecision(12);
  for (const auto& p : points) f << p.x() << "," << p.y() << "," << p.z() << "\n";
  f.close();
  if (!f) throw FileError(path, "write failed");
}

void write_replay_points(const fs::path& path, const Eigen::Isometry3d& T_camL_panel0,
                         const std::vector<Eigen::Vector2d>& panel_points) {
  std::vector<Eigen::Vector3d> points;
  for (const auto& q : panel_points) points.push_back(T_camL_panel0 * Eigen::Vector3d(q.x(), q.y(), 0.0));
  write_replay_points(path, points);
}

std::string replay_image_name(long index) {
  std::ostringstream name;
  name << std::setw(6) << std::setfill('0') << index << ".png";
  return name.str();
}

ReplayFrameWriter::ReplayFrameWriter(const fs::path& dir)
    : frames_path_(dir / "frames.csv"),
      truth_path_(dir / "truth.csv"),
      frames_(frames_path_),
      truth_(truth_path_) {
  write_stereo_index_header(frames_);
  truth_ << "index,t,m00,m01,m02,m03,m10,m11,m12,m13,m20,m21,m22,m23\n" << std::setprecision(15);
}

void ReplayFrameWriter::add(long index, double t, const std::string& left, const std::string& right,
                            const Eigen::Matrix4d& M) {
  write_stereo_index_line(frames_, index, t, left, right);
  truth_ << index << "," << t;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) truth_ << "," << M(r, c);
  truth_ << "\n";
}

void ReplayFrameWriter::finish() {
  frames_.close();
  if (!frames_) throw FileError(frames_path_, "write failed");
  truth_.close();
  if (!truth_) throw FileError(truth_path_, "write failed");
}

}  // namespace dentmark::files
