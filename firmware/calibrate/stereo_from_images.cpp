#include "dentmark/firmware/calibrate/stereo_from_images.h"

#include <algorithm>
#include <map>

#include "dentmark/common/image/image_file.h"
#include "dentmark/common/version.h"
#include "dentmark/firmware/calibrate/calibrate_error.h"
#include "dentmark/firmware/calibrate/input_digest.h"

namespace dentmark::calibrate {
namespace {

cv::Mat read_grey(const std::filesystem::path& p) {
  try {
    return image::read_grey_image(p.string());
  } catch (const image::ImageError& e) {
    throw CalibrateError(e.what());
  }
}

}  // namespace

StereoView stereo_view(const TargetSpec& target, const std::string& name, const Detection& left,
                       const Detection& right) {
  StereoView v;
  v.name = name;
  std::vector<cv::Point2f> right_corners = right.corners;
  if (target.kind == TargetKind::kChessboard && left.found && right.found) {
    // findChessboardCorners may start a board at either end (a 180° turn of the grid
    // maps the inner corners onto themselves). Cameras side by side see the board the
    // same way up, so the first-to-last corner direction must agree in both images.
    const cv::Point2f dl = left.corners.front() - left.corners.back();
    const cv::Point2f dr = right_corners.front() - right_corners.back();
    if (dl.dot(dr) < 0) std::reverse(right_corners.begin(), right_corners.end());
  }
  std::map<int, cv::Point2f> in_right;
  for (std::size_t i = 0; i < right.ids.size(); ++i) in_right[right.ids[i]] = right_corners[i];
  for (std::size_t i = 0; i < left.ids.size(); ++i) {
    const auto it = in_right.find(left.ids[i]);
    if (it == in_right.end()) continue;
    v.object.push_back(target.corner(left.ids[i]));
    v.left.push_back(left.corners[i]);
    v.right.push_back(it->second);
  }
  return v;
}

StereoCalibrationRun calibrate_stereo_images(const std::filesystem::path& dir, const TargetSpec& target,
                                             const StereoFitOptions& options) {
  StereoCalibrationRun run;
  run.target = target;
  run.pairs = find_image_pairs(dir);
  run.created_utc = utc_now_iso8601();
  run.tool_version = kVersion;

  // Read every image first, so a bad file is reported before minutes of detection.
  const std::size_t n = run.pairs.size();
  std::vector<cv::Mat> images(2 * n);
  std::vector<std::filesystem::path> files;
  cv::Size size;
  for (std::size_t i = 0; i < n; ++i)
    for (int s = 0; s < 2; ++s) {
      const auto& p = s == 0 ? run.pairs[i].left : run.pairs[i].right;
      images[2 * i + static_cast<std::size_t>(s)] = read_grey(p);
      files.push_back(p);
      const cv::Size sz = images[2 * i + static_cast<std::size_t>(s)].size();
      if (size.empty()) size = sz;
      if (sz != size)
        throw CalibrateError(p.string() + ": " + std::to_string(sz.width) + "x" + std::to_string(sz.height) +
                             " pixels, but " + files.front().filename().string() + " has " +
                             std::to_string(size.width) + "x" + std::to_string(size.height));
    }
  run.inputs_sha256 = inputs_sha256(target.describe() + '\0', files);

  std::vector<Detection> found(2 * n);
  cv::parallel_for_(cv::Range(0, static_cast<int>(2 * n)), [&](const cv::Range& r) {
    for (int k = r.start; k < r.end; ++k)
      found[static_cast<std::size_t>(k)] = detect_target(target, images[static_cast<std::size_t>(k)]);
  });

  std::vector<StereoView> views;
  std::vector<std::size_t> view_pair;
  run.views.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    ViewFigures& vf = run.views[i];
    vf.name = run.pairs[i].name;
    const Detection& l = found[2 * i];
    const Detection& r = found[2 * i + 1];
    if (!l.found || !r.found) {
      vf.rejected_because = !l.found ? "left: " + l.why : "right: " + r.why;
      if (!l.found && !r.found) vf.rejected_because += "; right: " + r.why;
      continue;
    }
    StereoView v = stereo_view(target, vf.name, l, r);
    if (v.object.size() < 6) {
      vf.rejected_because = std::to_string(v.object.size()) + " corners seen by both cameras (need 6)";
      continue;
    }
    views.push_back(std::move(v));
    view_pair.push_back(i);
  }
  const int need = std::max(options.min_views, 3);
  if (static_cast<int>(views.size()) < need)
    throw CalibrateError(dir.string() + ": the target (" + target.describe() +
                         ") was found in both images of " + std::to_string(views.size()) + " of " +
                         std::to_string(n) + " pairs; at least " + std::to_string(need) +
                         " are needed (check --pattern and --square)");
  run.fit = fit_stereo(views, size, target.square_m, options);
  for (std::size_t k = 0; k < views.size(); ++k) run.views[view_pair[k]] = run.fit.views[k];
  return run;
}

}  // namespace dentmark::calibrate
