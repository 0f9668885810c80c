#pragma once
// Runs a rendered sequence through the tracker frame by frame and breaks its error down
// against the renderer's ground truth: the motion error at the evaluation points (mean,
// worst, per camL axis), and per feature the pixel error of the tracked corner in each
// camera and of its disparity (the left minus right x error), as bias (mean over the
// run) and noise (standard deviation). Used by the accuracy tests on both renderers.

#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "dentmark/firmware/track/sequence.h"
#include "dentmark/firmware/track/tracker.h"

namespace dentmark::track::testing {

inline std::vector<std::vector<double>> read_csv_numbers(const std::filesystem::path& path) {
  std::ifstream f(path);
  std::string line;
  std::getline(f, line);
  std::vector<std::vector<double>> rows;
  while (std::getline(f, line)) {
    if (line.empty()) continue;
    std::vector<double> row;
    std::stringstream s(line);
    std::string cell;
    while (std::getline(s, cell, ',')) row.push_back(std::stod(cell));
    rows.push_back(row);
  }
  return rows;
}

struct FrameError {
  long index = 0;
  double t = 0.0;
  bool ok = false;
  double mean = 0.0, worst = 0.0;                  // m, over the evaluation points
  Eigen::Vector3d axis = Eigen::Vector3d::Zero();  // mean |error| per camL axis, m
  double raw_mean = 0.0;                           // m: this frame's fit alone, before the motion filter
  Eigen::Vector3d signed_centre = Eigen::Vector3d::Zero();  // m: error at the points' centroid
  double quality = 0.0;
  double expected_error = 0.0;  // the tracker's own figure, m
};

struct FeatureError {
  int samples = 0;
  double disparity_bias = 0.0, disparity_noise = 0.0;  // px
  double left_bias = 0.0, right_bias = 0.0;            // px, x error
};

struct AccuracyReport {
  std::vector<FrameError> frames;
  std::vector<FeatureError> features;  // by seed
  int failed = 0;
  double mean = 0.0, worst = 0.0;  // m, over ok frames
  Eigen::Vector3d axis = Eigen::Vector3d::Zero();
  double ms_per_frame = 0.0;

  void print(const std::string& name) const {
    std::printf("%s: frames %zu failed %d: mean %.3f mm, worst %.3f mm; per axis x %.3f y %.3f z %.3f mm\n",
                name.c_str(), frames.size(), failed, mean * 1e3, worst * 1e3, axis.x() * 1e3, axis.y() * 1e3,
                axis.z() * 1e3);
    if (std::getenv("DENTMARK_ACCURACY_FRAMES"))
      for (const auto& f : frames)
        std::printf(
            "  frame %ld t %.2f ok %d: mean %.3f raw %.3f mm; centre error %+.3f %+.3f %+.3f mm; expected "
            "%.3f mm\n",
            f.index, f.t, f.ok, f.mean * 1e3, f.raw_mean * 1e3, f.signed_centre.x() * 1e3,
            f.signed_centre.y() * 1e3, f.signed_centre.z() * 1e3, f.expected_error * 1e3);
    for (std::size_t i = 0; i < features.size(); ++i)
      if (features[i].samples > 0)
        std::printf(
            "  feature %zu: disparity bias %+.3f px noise %.3f px (left x bias %+.3f, right %+.3f) n=%d\n", i,
            features[i].disparity_bias, features[i].disparity_noise, features[i].left_bias,
            features[i].right_bias, features[i].samples);
  }
};

inline double pearson(const std::vector<double>& a, const std::vector<double>& b) {
  const double n = static_cast<double>(a.size());
  double ma = 0, mb = 0;
  for (std::size_t i = 0; i < a.size(); ++i) ma += a[i] / n, mb += b[i] / n;
  double sab = 0, saa = 0, sbb = 0;
  for (std::size_t i = 0; i < a.size(); ++i)
    sab += (a[i] - ma) * (b[i] - mb), saa += (a[i] - ma) * (a[i] - ma), sbb += (b[i] - mb) * (b[i] - mb);
  return sab / std::sqrt(saa * sbb);
}

inline AccuracyReport measure(const std::filesystem::path& dir, const TrackerOptions& options = {}) {
  const Sequence seq = load_sequence(dir);
  const auto seeds = load_seeds(dir / "seeds.yaml", seq.calibration.size);
  const auto truth_rows = read_csv_numbers(dir / "truth.csv");
  std::vector<Eigen::Vector3d> eval, feats;
  for (const auto& r : read_csv_numbers(dir / "eval_points.csv")) eval.emplace_back(r[0], r[1], r[2]);
  for (const auto& r : read_csv_numbers(dir / "features.csv")) feats.emplace_back(r[0], r[1], r[2]);
  auto truth_of = [&](std::size_t k) {
    Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) m.matrix()(r, c) = truth_rows[k][static_cast<std::size_t>(2 + 4 * r + c)];
    return m;
  };
  Tracker tracker(seq.calibration, options);
  AccuracyReport rep;
  std::vector<std::vector<double>> dl(seeds.size()), dr(seeds.size());
  double seconds = 0.0;
  for (std::size_t k = 0; k < seq.frames.size(); ++k) {
    const auto& f = seq.frames[k];
    const cv::Mat l = load_grey(f.left, seq.calibration.size), r = load_grey(f.right, seq.calibration.size);
    const auto t0 = std::chrono::steady_clock::now();
    const FrameResult res =
        k == 0 ? tracker.start(l, r, f.t, seeds, f.index) : tracker.track(l, r, f.t, f.index);
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const Eigen::Isometry3d truth = truth_of(k);
    FrameError fe;
    fe.index = f.index;
    fe.t = f.t;
    fe.ok = res.ok;
    fe.quality = res.quality;
    fe.expected_error = res.expected_error;
    for (const auto& p : eval) {
      const Eigen::Vector3d e = res.motion * p - truth * p;
      fe.mean += e.norm() / static_cast<double>(eval.size());
      fe.worst = std::max(fe.worst, e.norm());
      fe.axis += e.cwiseAbs() / static_cast<double>(eval.size());
      fe.raw_mean += (res.raw_motion * p - truth * p).norm() / static_cast<double>(eval.size());
      fe.signed_centre += e / static_cast<double>(eval.size());
    }
    rep.frames.push_back(fe);
    if (!res.ok) {
      ++rep.failed;
      continue;
    }
    // Per feature: where it should be in each image against where the tracker has it.
    const auto& tracked = tracker.tracked();
    for (std::size_t i = 0; i < tracked.size(); ++i) {
      if (k > 0 && !tracked[i]) continue;
      const int seed = tracker.seed_of_feature()[i];
      const Eigen::Vector3d x = truth * feats[static_cast<std::size_t>(seed)];
      const cv::Point2f tl = seq.calibration.project(Cam::kLeft, {x})[0];
      const cv::Point2f tr = seq.calibration.project(Cam::kRight, {x})[0];
      dl[static_cast<std::size_t>(seed)].push_back(tracker.left_points()[i].x - tl.x);
      dr[static_cast<std::size_t>(seed)].push_back(tracker.right_points()[i].x - tr.x);
    }
  }
  rep.ms_per_frame = 1e3 * seconds / static_cast<double>(seq.frames.size());
  int ok = 0;
  for (const auto& f : rep.frames)
    if (f.ok) {
      ++ok;
      rep.mean += f.mean;
      rep.worst = std::max(rep.worst, f.worst);
      rep.axis += f.axis;
    }
  if (ok > 0) rep.mean /= ok, rep.axis /= ok;
  rep.features.resize(seeds.size());
  for (std::size_t i = 0; i < seeds.size(); ++i) {
    FeatureError& e = rep.features[i];
    e.samples = static_cast<int>(dl[i].size());
    if (e.samples == 0) continue;
    double s = 0, s2 = 0, sl = 0, sr = 0;
    for (std::size_t j = 0; j < dl[i].size(); ++j) {
      const double d = dl[i][j] - dr[i][j];
      s += d, s2 += d * d, sl += dl[i][j], sr += dr[i][j];
    }
    const double n = e.samples;
    e.disparity_bias = s / n;
    e.disparity_noise = std::sqrt(std::max(0.0, s2 / n - e.disparity_bias * e.disparity_bias));
    e.left_bias = sl / n;
    e.right_bias = sr / n;
  }
  return rep;
}

}  // namespace dentmark::track::testing
