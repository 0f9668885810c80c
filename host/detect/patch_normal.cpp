#include "patch_normal.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <vector>

#include "dentmark/common/geometry/plane_fit.h"

namespace dentmark::detect {

Eigen::Vector3d patch_normal(const HeightMap& map, double side, int row, int col, const cv::Mat& exclude) {
  const Eigen::Vector3d w_axis = map.axes.row(2).transpose();
  std::vector<Eigen::Vector3d> pts;
  std::vector<double> wts;
  const int hp = std::max(1, static_cast<int>(std::lround(0.5 * side / map.pixel)));
  for (int r = std::max(0, row - hp); r <= std::min(map.rows - 1, row + hp); ++r)
    for (int c = std::max(0, col - hp); c <= std::min(map.cols - 1, col + hp); ++c) {
      const int k = r * map.cols + c;
      if (!(map.weight[k] > 0.0f) || exclude.data[k]) continue;
      pts.push_back(map.to_scan(map.u[k], map.v[k], map.w[k]));
      wts.push_back(map.weight[k]);
    }
  try {
    if (pts.size() >= 3) return fit_plane(pts, wts, w_axis).normal;
  } catch (const std::exception&) {
  }
  return w_axis;
}

}  // namespace dentmark::detect
