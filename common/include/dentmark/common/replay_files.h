#pragma once
// The side files of the tracker's replay format, as both stereo renderers write them
// (sim/stereo and sim/stereo_raytrace are independent image models; the format they
// write is one). A replay folder holds stereo.yaml (the rig), frames.csv (stereo_index.h)
// and these:
//   seeds.yaml       seeds_right: an N x 2 float matrix (OpenCV FileStorage), rough
//                    right-image corners of the features in frame 0; the tracker reads it
//                    with track::load_seeds.
//   eval_points.csv  header `x,y,z`, one point a line (m, camL at frame 0, 12 significant
//   features.csv     digits): points on the panel to score motion at, and the features.
//   truth.csv        header `index,t,m00,...,m23`, one line a frame: its counter, its time
//                    (s) and the top three rows of the true motion M(k) (camL at frame 0 to
//                    camL at frame k), row by row, 15 significant digits.
// Every writer throws FileError naming the file when a write fails.

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>
#include <opencv2/core/types.hpp>
#include <string>
#include <vector>

namespace dentmark::files {

void write_replay_seeds(const std::filesystem::path& path, const std::vector<cv::Point2f>& seeds_right);

void write_replay_points(const std::filesystem::path& path, const std::vector<Eigen::Vector3d>& points);
// The same for points in the panel's plane (x, y; z = 0 in the panel's frame), written
// where they are in camL at frame 0: T_camL_panel0 * (x, y, 0).
void write_replay_points(const std::filesystem::path& path, const Eigen::Isometry3d& T_camL_panel0,
                         const std::vector<Eigen::Vector2d>& panel_points);

// The file name of frame `index`'s images, six digits and ".png" (000012.png): the left
// one is left/NAME, the right one right/NAME, relative to the folder.
std::string replay_image_name(long index);

// frames.csv and truth.csv of a replay folder, a line each per frame, in frame order.
class ReplayFrameWriter {
 public:
  explicit ReplayFrameWriter(const std::filesystem::path& dir);  // writes both headers
  // Frame `index` at time t (s): its two image files (relative to the folder) and its
  // true motion M (only the top three rows are written).
  void add(long index, double t, const std::string& left, const std::string& right, const Eigen::Matrix4d& M);
  void finish();  // flushes and closes both files; throws FileError if any write failed

 private:
  std::filesystem::path frames_path_, truth_path_;
  std::ofstream frames_, truth_;
};

}  // namespace dentmark::files
