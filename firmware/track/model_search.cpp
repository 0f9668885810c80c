#include "dentmark/firmware/track/model_search.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "dentmark/common/geometry/rigid_fit.h"
#include "dentmark/firmware/track/track_error.h"

namespace dentmark::track {
namespace {

struct Peak {
  cv::Point2f p;  // level 0, px
  double ncc = 0.0;
};

// Best match of templ whose centre lies within ±radius of `around` (level pixels);
// nothing when the window leaves the image.
std::optional<std::pair<cv::Point, double>> best_near(const cv::Mat& level, const cv::Mat& templ,
                                                      cv::Point around, int radius, cv::Mat* score_out) {
  const int h = templ.cols / 2;
  const cv::Rect area(around.x - radius - h, around.y - radius - h, 2 * (radius + h) + 1,
                      2 * (radius + h) + 1);
  if ((area & cv::Rect(0, 0, level.cols, level.rows)) != area) return std::nullopt;
  cv::Mat score;
  cv::matchTemplate(level(area), templ, score, cv::TM_CCOEFF_NORMED);
  double best;
  cv::Point loc;
  cv::minMaxLoc(score, nullptr, &best, nullptr, &loc);
  if (score_out) *score_out = score;
  return std::make_pair(cv::Point(area.x + loc.x + h, area.y + loc.y + h), best);
}

// Sub-pixel peak of a score map by a parabola through the maximum and its neighbours.
cv::Point2f parabola_peak(const cv::Mat& score, cv::Point loc) {
  auto vertex = [](float a, float b, float c) {
    const float d = a - 2 * b + c;
    return d < 0 ? std::clamp(0.5f * (a - c) / d, -0.5f, 0.5f) : 0.0f;
  };
  cv::Point2f off(0, 0);
  if (loc.x > 0 && loc.x + 1 < score.cols)
    off.x =
        vertex(score.at<float>(loc.y, loc.x - 1), score.at<float>(loc), score.at<float>(loc.y, loc.x + 1));
  if (loc.y > 0 && loc.y + 1 < score.rows)
    off.y =
        vertex(score.at<float>(loc.y - 1, loc.x), score.at<float>(loc), score.at<float>(loc.y + 1, loc.x));
  return cv::Point2f(static_cast<float>(loc.x), static_cast<float>(loc.y)) + off;
}

// Where one feature's templates match in one image: the best coarse peaks, each
// followed down the pyramid (±2 px per level) and fitted to a sub-pixel peak.
std::vector<Peak> find_peaks(const std::vector<cv::Mat>& pyramid, const std::vector<cv::Mat>& templ,
                             const ModelSearchOptions& o) {
  const int top = static_cast<int>(templ.size()) - 1;
  const cv::Mat& coarse = pyramid[static_cast<std::size_t>(top)];
  const cv::Mat& t = templ[static_cast<std::size_t>(top)];
  std::vector<Peak> out;
  if (coarse.cols < t.cols || coarse.rows < t.rows) return out;
  cv::Mat score;
  cv::matchTemplate(coarse, t, score, cv::TM_CCOEFF_NORMED);
  const int h = t.cols / 2, suppress = std::max(2, h / 2);
  for (int k = 0; k < o.peaks; ++k) {
    double best;
    cv::Point loc;
    cv::minMaxLoc(score, nullptr, &best, nullptr, &loc);
    if (!(best >= o.min_coarse_ncc)) break;
    // Non-maximum suppression: the next peak is another place, not this one's flank.
    cv::rectangle(score, cv::Rect(loc.x - suppress, loc.y - suppress, 2 * suppress + 1, 2 * suppress + 1),
                  cv::Scalar(-1.0), cv::FILLED);
    cv::Point pos(loc.x + h, loc.y + h);
    std::optional<std::pair<cv::Point, double>> m = std::make_pair(pos, best);
    cv::Mat fine_score;
    for (int l = top - 1; l >= 0 && m; --l)
      m = best_near(pyramid[static_cast<std::size_t>(l)], templ[static_cast<std::size_t>(l)], m->first * 2, 2,
                    l == 0 ? &fine_score : nullptr);
    if (!m || !(m->second >= o.min_ncc)) continue;
    cv::Point2f p(static_cast<float>(m->first.x), static_cast<float>(m->first.y));
    if (!fine_score.empty()) {
      cv::Point floc;
      cv::minMaxLoc(fine_score, nullptr, nullptr, nullptr, &floc);
      p += parabola_peak(fine_score, floc) -
           cv::Point2f(static_cast<float>(floc.x), static_cast<float>(floc.y));
    }
    // Two coarse peaks that converged on one place count once.
    if (std::none_of(out.begin(), out.end(), [&](const Peak& q) { return cv::norm(q.p - p) < 1.5; }))
      out.push_back({p, m->second});
  }
  return out;
}

struct Candidate {
  Eigen::Vector3d p_camL;
  cv::Point2f right;
  double score = 0.0;
};

// --- The stages of search_model ---

// Per taught feature, its candidate places in 3D: every pair of its peaks in the two
// views (find_peaks) that triangulates within max_reprojection and 0.3-30 m away, best
// score first, at most 8. The taught features are corners the pixels sit on; the patch's
// grid offset is the model's pixel minus its rounded value.
std::vector<std::vector<Candidate>> feature_candidates(const StereoCalibration& calib,
                                                       const std::vector<cv::Mat>& pl,
                                                       const std::vector<cv::Mat>& pr,
                                                       const PanelModel& model, const ModelSearchOptions& o) {
  const std::size_t n = model.features.size();
  std::vector<std::vector<Candidate>> cands(n);
  for (std::size_t i = 0; i < n; ++i) {
    const ModelFeature& f = model.features[i];
    const auto off = [](const cv::Point2f& p) {
      return p - cv::Point2f(static_cast<float>(cvRound(p.x)), static_cast<float>(cvRound(p.y)));
    };
    const std::vector<Peak> in_left = find_peaks(pl, f.left, o), in_right = find_peaks(pr, f.right, o);
    for (const Peak& r : in_right)
      for (const Peak& l : in_left) {
        const cv::Point2f pl0 = l.p + off(f.pixel_left), pr0 = r.p + off(f.pixel_right);
        const Triangulation tri =
            triangulate(calib, calib.normalize(Cam::kLeft, {pl0})[0], calib.normalize(Cam::kRight, {pr0})[0]);
        if (tri.reprojection_px > o.max_reprojection || !(tri.p_camL.z() > 0.3) || !(tri.p_camL.z() < 30.0))
          continue;
        cands[i].push_back({tri.p_camL, pr0, l.ncc + r.ncc});
      }
    std::sort(cands[i].begin(), cands[i].end(),
              [](const Candidate& a, const Candidate& b) { return a.score > b.score; });
    if (cands[i].size() > 8) cands[i].resize(8);
  }
  return cands;
}

// Consensus of a motion: per feature the candidate nearest to the moved taught point.
struct Consensus {
  std::vector<int> pick;  // candidate index per feature, -1: none
  int count = 0;
  double sq = 0.0;  // sum of the squared distances of the picks (m²)
  bool better_than(const Consensus& b) const { return count > b.count || (count == b.count && sq < b.sq); }
};

// The candidates against the taught layout: how far a candidate may lie from where a
// motion puts its feature (the stereo depth error at its depth, `sigmas` times, at least
// min_tolerance), and which motions they agree on.
class LayoutMatch {
 public:
  LayoutMatch(const StereoCalibration& calib, const PanelModel& model,
              std::vector<std::vector<Candidate>>& cands, const ModelSearchOptions& o)
      : model_(model),
        cands_(cands),
        o_(o),
        f_px_(0.5 * (calib.left.K(0, 0) + calib.right.K(0, 0))),
        baseline_(calib.T_camR_camL.translation().norm()) {}

  double tolerance(double z) const {
    return std::max(o_.min_tolerance, o_.sigmas * z * z / (f_px_ * baseline_) * o_.match_noise);
  }
  const Eigen::Vector3d& taught(std::size_t i) const { return model_.features[i].p_camL; }

  Consensus consensus_of(const Transform& t) const {
    const std::size_t n = cands_.size();
    Consensus c;
    c.pick.assign(n, -1);
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d x = t * taught(i);
      double best = tolerance(x.z());
      for (std::size_t k = 0; k < cands_[i].size(); ++k) {
        const double d = (cands_[i][k].p_camL - x).norm();
        if (d <= best) best = d, c.pick[i] = static_cast<int>(k);
      }
      if (c.pick[i] >= 0) ++c.count, c.sq += best * best;
    }
    return c;
  }

  // Two candidates as far apart as their taught features, within tolerance.
  bool agrees(std::size_t i, const Candidate& ci, std::size_t j, const Candidate& cj) const {
    const double d = std::abs((ci.p_camL - cj.p_camL).norm() - (taught(i) - taught(j)).norm());
    return d <= tolerance(std::max(ci.p_camL.z(), cj.p_camL.z()));
  }

  // The motion with the largest consensus over every triplet of non-collinear features
  // and every triplet of their candidates that agree pairwise.
  void best_triplet(Consensus& best, Transform& best_t) const {
    const std::size_t n = cands_.size();
    for (std::size_t a = 0; a < n; ++a)
      for (std::size_t b = a + 1; b < n; ++b)
        for (std::size_t c = b + 1; c < n; ++c) {
          if ((taught(b) - taught(a)).cross(taught(c) - taught(a)).norm() < 1e-4) continue;  // collinear
          for (const Candidate& ca : cands_[a])
            for (const Candidate& cb : cands_[b]) {
              if (!agrees(a, ca, b, cb)) continue;
              for (const Candidate& cc : cands_[c]) {
                if (!agrees(a, ca, c, cc) || !agrees(b, cb, c, cc)) continue;
                const std::vector<Eigen::Vector3d> from{taught(a), taught(b), taught(c)},
                    to{ca.p_camL, cb.p_camL, cc.p_camL};
                try {
                  const Transform t = fit_rigid(from, to).T_to_from;
                  Consensus s = consensus_of(t);
                  if (s.better_than(best)) best = std::move(s), best_t = t;
                } catch (const GeometryError&) {
                }
              }
            }
        }
  }

  // The motion refitted on the whole consensus, twice (a triplet's motion is only as good
  // as its three points), kept while the consensus does not shrink.
  void polish(Consensus& best, Transform& best_t) const {
    const std::size_t n = cands_.size();
    for (int it = 0; it < 2 && best.count >= 3; ++it) {
      std::vector<Eigen::Vector3d> from, to;
      for (std::size_t i = 0; i < n; ++i)
        if (best.pick[i] >= 0)
          from.push_back(taught(i)), to.push_back(cands_[i][static_cast<std::size_t>(best.pick[i])].p_camL);
      try {
        const Transform t = fit_rigid(from, to).T_to_from;
        Consensus s = consensus_of(t);
        if (s.count < best.count) break;
        best = std::move(s), best_t = t;
      } catch (const GeometryError&) {
        break;
      }
    }
  }

  // Features the coarse search missed (near the border, where the coarse patch does not
  // fit, or partly hidden): looked for with the finest templates where the motion puts
  // them, and added to the consensus when both views agree with that place in 3D.
  void recover_missed(const StereoCalibration& calib, const cv::Mat& left, const cv::Mat& right,
                      const Transform& best_t, Consensus& best) {
    for (std::size_t i = 0; i < cands_.size(); ++i) {
      if (best.pick[i] >= 0) continue;
      const ModelFeature& f = model_.features[i];
      const Eigen::Vector3d x = best_t * taught(i);
      const cv::Point2f gl = calib.project(Cam::kLeft, {x})[0], gr = calib.project(Cam::kRight, {x})[0];
      auto look = [&](const cv::Mat& image, const cv::Mat& templ, const cv::Point2f& g,
                      const cv::Point2f& taught_px) -> std::optional<cv::Point2f> {
        const cv::Point2f off = taught_px - cv::Point2f(static_cast<float>(cvRound(taught_px.x)),
                                                        static_cast<float>(cvRound(taught_px.y)));
        cv::Mat score;
        const auto m =
            best_near(image, templ, cv::Point(cvRound(g.x - off.x), cvRound(g.y - off.y)), 4, &score);
        if (!m || !(m->second >= o_.min_ncc)) return std::nullopt;
        cv::Point loc;
        cv::minMaxLoc(score, nullptr, nullptr, nullptr, &loc);
        return cv::Point2f(static_cast<float>(m->first.x), static_cast<float>(m->first.y)) + off +
               parabola_peak(score, loc) - cv::Point2f(static_cast<float>(loc.x), static_cast<float>(loc.y));
      };
      const auto l = look(left, f.left[0], gl, f.pixel_left);
      const auto rr = l ? look(right, f.right[0], gr, f.pixel_right) : std::nullopt;
      if (!rr) continue;
      const Triangulation tri =
          triangulate(calib, calib.normalize(Cam::kLeft, {*l})[0], calib.normalize(Cam::kRight, {*rr})[0]);
      const double d = (tri.p_camL - x).norm();
      if (tri.reprojection_px > o_.max_reprojection || d > tolerance(x.z())) continue;
      cands_[i].push_back({tri.p_camL, *rr, 0.0});
      best.pick[i] = static_cast<int>(cands_[i].size() - 1);
      ++best.count;
      best.sq += d * d;
    }
  }

 private:
  const PanelModel& model_;
  std::vector<std::vector<Candidate>>& cands_;
  const ModelSearchOptions& o_;
  double f_px_, baseline_;
};

}  // namespace

ModelSearchResult search_model(const StereoCalibration& calib, const cv::Mat& left, const cv::Mat& right,
                               const PanelModel& model, const ModelSearchOptions& o) {
  const std::size_t n = model.features.size();
  const auto pl = model_pyramid(left, model.levels), pr = model_pyramid(right, model.levels);
  std::vector<std::vector<Candidate>> cands = feature_candidates(calib, pl, pr, model, o);
  LayoutMatch match(calib, model, cands, o);
  Consensus best;
  Transform best_t = Transform::Identity();
  match.best_triplet(best, best_t);
  const int need = std::max(4, static_cast<int>(std::ceil(o.min_share * static_cast<double>(n))));
  match.polish(best, best_t);
  if (best.count < need)
    throw TrackError("panel model not found: at most " + std::to_string(best.count) + " of " +
                     std::to_string(n) + " taught features agree with the taught layout (need " +
                     std::to_string(need) + ")");
  match.recover_missed(calib, left, right, best_t, best);
  ModelSearchResult r;
  r.seeds_right.assign(n, std::nullopt);
  r.found = best.count;
  r.T_now_taught = best_t;
  r.rms = std::sqrt(best.sq / best.count);
  for (std::size_t i = 0; i < n; ++i)
    if (best.pick[i] >= 0) r.seeds_right[i] = cands[i][static_cast<std::size_t>(best.pick[i])].right;
  return r;
}

}  // namespace dentmark::track
