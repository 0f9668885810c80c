#include "fold_mesher.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <queue>
#include <unordered_map>

#include "delaunay_mesher.h"

namespace dentmark::ingest {
namespace {

constexpr double kPointsPerCell = 100.0;  // enough for a plane fit well above the noise
constexpr double kEdgeOnDegrees = 80.0;   // a single view sees little of a surface beyond
constexpr double kFoldedShare = 0.01;     // of the points, in cells beyond that
constexpr double kCoverDegrees = 35.0;    // every chart's own cells within this of its axis
constexpr double kReachDegrees = 65.0;    // a chart meshes the cells within this (overlap)
constexpr double kUncoveredShare = 0.005;
constexpr std::size_t kMaxCharts = 8;

double cos_degrees(double d) {
  return std::cos(d * std::numbers::pi / 180.0);
}

// The cloud cut into cubes, each with a plane fitted to its points.
struct Cell {
  std::array<std::int32_t, 3> index{};
  std::size_t count = 0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();    // of its points
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // unit; oriented by orient_cells
  bool planar = false;
  int owner = -1;  // the chart whose triangles cover this cell
};

class Grid {
 public:
  Grid(const std::vector<Eigen::Vector3f>& pts, const std::vector<std::uint32_t>& valid, double size)
      : size_(size) {
    origin_ = pts[valid[0]].cast<double>();
    for (const std::uint32_t i : valid) origin_ = origin_.cwiseMin(pts[i].cast<double>());
    point_cell_.assign(pts.size(), 0);
    lookup_.reserve(valid.size() / 32 + 16);  // (not rehashed as it grows)
    for (const std::uint32_t i : valid) {
      const Eigen::Vector3d p = pts[i].cast<double>();
      const auto idx = index_of(p);
      auto [it, fresh] = lookup_.try_emplace(key(idx), static_cast<std::uint32_t>(cells_.size()));
      if (fresh) cells_.push_back(Cell{idx});
      Cell& c = cells_[it->second];
      ++c.count;
      const Eigen::Vector3d d = p - origin_;  // well conditioned sums
      c.sum += d;
      c.outer += d * d.transpose();
      point_cell_[i] = it->second;
    }
    for (Cell& c : cells_) c.mean = origin_ + c.sum / static_cast<double>(c.count);
  }

  std::vector<Cell>& cells() { return cells_; }
  const std::vector<Cell>& cells() const { return cells_; }
  std::uint32_t cell_of_point(std::uint32_t i) const { return point_cell_[i]; }

  template <typename Visit>
  void for_each_neighbour(std::uint32_t c, Visit visit) const {
    const auto& idx = cells_[c].index;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          if (dx == 0 && dy == 0 && dz == 0) continue;
          const std::int64_t n = find({idx[0] + dx, idx[1] + dy, idx[2] + dz});
          if (n >= 0) visit(static_cast<std::uint32_t>(n));
        }
  }

 private:
  std::array<std::int32_t, 3> index_of(const Eigen::Vector3d& p) const {
    const Eigen::Vector3d q = (p - origin_) / size_;
    return {static_cast<std::int32_t>(std::floor(q.x())), static_cast<std::int32_t>(std::floor(q.y())),
            static_cast<std::int32_t>(std::floor(q.z()))};
  }
  static std::uint64_t key(const std::array<std::int32_t, 3>& i) {
    const auto part = [](std::int32_t v) { return static_cast<std::uint64_t>(v + (1 << 20)) & 0x1fffff; };
    return part(i[0]) | part(i[1]) << 21 | part(i[2]) << 42;
  }
  std::int64_t find(const std::array<std::int32_t, 3>& i) const {
    const auto it = lookup_.find(key(i));
    return it == lookup_.end() ? -1 : static_cast<std::int64_t>(it->second);
  }

  double size_;
  Eigen::Vector3d origin_;
  std::vector<Cell> cells_;
  std::unordered_map<std::uint64_t, std::uint32_t> lookup_;
  std::vector<std::uint32_t> point_cell_;
};

// Cubes holding about kPointsPerCell of the points 'ids' each, whatever the cloud's density
// and units; measured on at most 200 000 of them.
double cell_size(const std::vector<Eigen::Vector3f>& pts, const std::vector<std::uint32_t>& ids) {
  Eigen::Vector3d lo = pts[ids[0]].cast<double>(), hi = lo;
  for (const std::uint32_t i : ids) {
    lo = lo.cwiseMin(pts[i].cast<double>());
    hi = hi.cwiseMax(pts[i].cast<double>());
  }
  const double diagonal = std::max((hi - lo).norm(), 1e-9);
  const double first = diagonal / 100.0;
  const std::size_t stride = (ids.size() + 199999) / 200000;
  std::vector<std::uint32_t> sample;
  for (std::size_t i = 0; i < ids.size(); i += stride) sample.push_back(ids[i]);
  const Grid coarse(pts, sample, first);
  const double per_cell = static_cast<double>(ids.size()) / static_cast<double>(coarse.cells().size());
  // A surface's cells hold points in proportion to their face's area.
  return std::clamp(first * std::sqrt(kPointsPerCell / per_cell), diagonal / 400.0, diagonal / 12.0);
}

void fit_planes(std::vector<Cell>& cells) {
  for (Cell& c : cells) {
    if (c.count < 10) continue;
    const double n = static_cast<double>(c.count);
    const Eigen::Vector3d mean = c.sum / n;
    const Eigen::Matrix3d cov = c.outer / n - mean * mean.transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    c.normal = eig.eigenvectors().col(0);
    // Points spread in a plane, not across a fold or a depth jump.
    c.planar = eig.eigenvalues()(1) > 0.0 && eig.eigenvalues()(0) < 0.05 * eig.eigenvalues()(1);
  }
}

// Hoppe et al.'s orientation: from the cell facing the viewer most squarely, across the
// most nearly parallel neighbours first, each normal turned to agree with the one it was
// reached from.
void orient_cells(Grid& grid, const ViewDirection& view) {
  auto& cells = grid.cells();
  std::vector<bool> done(cells.size(), false);
  using Step = std::pair<double, std::pair<std::uint32_t, std::uint32_t>>;  // (1-|cos|, (from, to))
  for (;;) {
    std::int64_t seed = -1;
    double best = -1.0;
    for (std::uint32_t c = 0; c < cells.size(); ++c) {
      if (!cells[c].planar || done[c]) continue;
      const double facing = std::abs(cells[c].normal.dot(view.towards_viewer(cells[c].mean)));
      if (facing > best) best = facing, seed = c;
    }
    if (seed < 0) return;
    Cell& s = cells[static_cast<std::size_t>(seed)];
    if (s.normal.dot(view.towards_viewer(s.mean)) < 0.0) s.normal = -s.normal;
    std::priority_queue<Step, std::vector<Step>, std::greater<>> queue;
    const auto reach = [&](std::uint32_t from) {
      done[from] = true;
      grid.for_each_neighbour(from, [&](std::uint32_t to) {
        if (cells[to].planar && !done[to])
          queue.push({1.0 - std::abs(cells[from].normal.dot(cells[to].normal)), {from, to}});
      });
    };
    reach(static_cast<std::uint32_t>(seed));
    while (!queue.empty()) {
      const auto [from, to] = queue.top().second;
      queue.pop();
      if (done[to]) continue;
      if (cells[to].normal.dot(cells[from].normal) < 0.0) cells[to].normal = -cells[to].normal;
      reach(to);
    }
  }
}

// Axes (unsigned) such that all but kUncoveredShare of the planar cells' points lie within
// kCoverDegrees of one: farthest-first seeds refined by a few rounds of k-means.
std::vector<Eigen::Vector3d> chart_axes(const std::vector<Cell>& cells) {
  const double cover = cos_degrees(kCoverDegrees);
  double total = 0.0;
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const Cell& c : cells)
    if (c.planar) {
      total += static_cast<double>(c.count);
      scatter += static_cast<double>(c.count) * c.normal * c.normal.transpose();
    }
  std::vector<Eigen::Vector3d> axes{
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvectors().col(2)};
  const auto nearest = [&](const Eigen::Vector3d& n) {
    std::size_t k = 0;
    for (std::size_t j = 1; j < axes.size(); ++j)
      if (std::abs(n.dot(axes[j])) > std::abs(n.dot(axes[k]))) k = j;
    return k;
  };
  for (;;) {
    double uncovered = 0.0, worst = 2.0;
    const Cell* farthest = nullptr;
    for (const Cell& c : cells) {
      if (!c.planar) continue;
      const double fit = std::abs(c.normal.dot(axes[nearest(c.normal)]));
      if (fit < cover) uncovered += static_cast<double>(c.count);
      if (fit < worst) worst = fit, farthest = &c;
    }
    if (uncovered <= kUncoveredShare * total || axes.size() >= kMaxCharts || farthest == nullptr) return axes;
    axes.push_back(farthest->normal);
    for (int round = 0; round < 3; ++round) {
      std::vector<Eigen::Matrix3d> sums(axes.size(), Eigen::Matrix3d::Zero());
      for (const Cell& c : cells)
        if (c.planar)
          sums[nearest(c.normal)] += static_cast<double>(c.count) * c.normal * c.normal.transpose();
      for (std::size_t k = 0; k < axes.size(); ++k)
        if (sums[k].trace() > 0.0)
          axes[k] = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(sums[k]).eigenvectors().col(2);
    }
  }
}

// Each cell's chart: a planar cell's nearest axis; any other cell (a fold, a depth jump,
// too few points) that of its most populous planar neighbour.
void assign_owners(Grid& grid, const std::vector<Eigen::Vector3d>& axes) {
  auto& cells = grid.cells();
  for (Cell& c : cells) {
    if (!c.planar) continue;
    double best = -1.0;
    for (std::size_t k = 0; k < axes.size(); ++k)
      if (std::abs(c.normal.dot(axes[k])) > best)
        best = std::abs(c.normal.dot(axes[k])), c.owner = static_cast<int>(k);
  }
  for (std::uint32_t i = 0; i < cells.size(); ++i) {
    if (cells[i].planar) continue;
    std::size_t most = 0;
    grid.for_each_neighbour(i, [&](std::uint32_t n) {
      if (cells[n].planar && cells[n].count > most) most = cells[n].count, cells[i].owner = cells[n].owner;
    });
    if (cells[i].owner < 0) cells[i].owner = 0;
  }
}

// Appends the triangles of chart k: each connected part of the cells within kReachDegrees
// of its axis, triangulated in the axis's plane; kept where the chart owns the cell of
// the triangle's first point (lowest index), and wound the way that part's cells face.
void mesh_chart(Mesh& mesh, const Grid& grid, const std::vector<std::uint32_t>& valid,
                const Eigen::Vector3d& axis, int k) {
  const auto& cells = grid.cells();
  const double reach = cos_degrees(kReachDegrees);
  std::vector<char> in(cells.size(), 0);
  for (std::uint32_t c = 0; c < cells.size(); ++c)
    in[c] = cells[c].owner == k || (cells[c].planar && std::abs(cells[c].normal.dot(axis)) >= reach);
  // A fold's or an edge's cells come with the chart's cells beside them.
  for (std::uint32_t c = 0; c < cells.size(); ++c)
    if (in[c] == 1 && cells[c].planar)
      grid.for_each_neighbour(c, [&](std::uint32_t n) {
        if (!cells[n].planar && !in[n]) in[n] = 2;
      });
  const Eigen::Vector3d u = axis.unitOrthogonal(), v = axis.cross(u);
  std::vector<int> part(cells.size(), -1);
  std::vector<std::vector<std::uint32_t>> parts;
  for (std::uint32_t c = 0; c < cells.size(); ++c) {
    if (!in[c] || part[c] >= 0) continue;
    const int p = static_cast<int>(parts.size());
    parts.emplace_back();
    std::vector<std::uint32_t> stack{c};
    part[c] = p;
    while (!stack.empty()) {
      const std::uint32_t at = stack.back();
      stack.pop_back();
      parts.back().push_back(at);
      grid.for_each_neighbour(at, [&](std::uint32_t n) {
        if (in[n] && part[n] < 0) part[n] = p, stack.push_back(n);
      });
    }
  }
  std::vector<std::vector<std::uint32_t>> points(parts.size());
  for (const std::uint32_t i : valid) {
    const int p = part[grid.cell_of_point(i)];
    if (p >= 0) points[static_cast<std::size_t>(p)].push_back(i);
  }
  std::vector<Eigen::Vector2d> img(mesh.vertices.size());
  for (std::size_t p = 0; p < parts.size(); ++p) {
    // Which way the part faces along the axis: its own cells' oriented normals.
    double facing = 0.0;
    bool owns = false;
    for (const std::uint32_t c : parts[p])
      if (cells[c].owner == k) {
        owns = true;
        if (cells[c].planar) facing += static_cast<double>(cells[c].count) * cells[c].normal.dot(axis);
      }
    if (!owns || points[p].size() < 3) continue;
    for (const std::uint32_t i : points[p]) {
      const Eigen::Vector3d q = mesh.vertices[i].cast<double>();
      img[i] = Eigen::Vector2d(q.dot(u), q.dot(v));
    }
    const std::size_t first = mesh.triangles.size();
    mesh_delaunay(mesh, img, points[p]);
    const auto kept =
        std::remove_if(mesh.triangles.begin() + static_cast<std::ptrdiff_t>(first), mesh.triangles.end(),
                       [&](const std::array<std::uint32_t, 3>& t) {
                         // (Its centroid's cell, a hash lookup per triangle, led
                         // the profile.)
                         const std::uint32_t c = grid.cell_of_point(std::min({t[0], t[1], t[2]}));
                         return cells[c].owner != k || part[c] != static_cast<int>(p);
                       });
    mesh.triangles.erase(kept, mesh.triangles.end());
    for (std::size_t t = first; t < mesh.triangles.size(); ++t) {
      auto& tri = mesh.triangles[t];
      const Eigen::Vector3d a = mesh.vertices[tri[0]].cast<double>();
      const Eigen::Vector3d n =
          (mesh.vertices[tri[1]].cast<double>() - a).cross(mesh.vertices[tri[2]].cast<double>() - a);
      if ((n.dot(axis) < 0.0) != (facing < 0.0)) std::swap(tri[1], tri[2]);
    }
  }
}

// More than kFoldedShare of the points lie in planar cells seen edge-on or from behind.
bool folds_over(Grid& grid, std::size_t points, const ViewDirection& view) {
  fit_planes(grid.cells());
  const double edge_on = cos_degrees(kEdgeOnDegrees);
  std::size_t folded = 0;
  for (const Cell& c : grid.cells())
    if (c.planar && std::abs(c.normal.dot(view.towards_viewer(c.mean))) < edge_on) folded += c.count;
  return static_cast<double>(folded) > kFoldedShare * static_cast<double>(points);
}

}  // namespace

std::size_t mesh_folded_cloud(Mesh& mesh, const std::vector<std::uint32_t>& valid,
                              const ViewDirection& view) {
  if (valid.size() < 1000) return 0;
  // The test on at most 200 000 of the points (a few cloud-wide passes cost more than
  // the test is worth on the many clouds that do not fold).
  const std::size_t stride = (valid.size() + 199999) / 200000;
  std::vector<std::uint32_t> sample;
  for (std::size_t i = 0; i < valid.size(); i += stride) sample.push_back(valid[i]);
  Grid coarse(mesh.vertices, sample, cell_size(mesh.vertices, sample));
  if (!folds_over(coarse, sample.size(), view)) return 0;
  Grid grid(mesh.vertices, valid, cell_size(mesh.vertices, valid));
  auto& cells = grid.cells();
  fit_planes(cells);
  orient_cells(grid, view);
  const std::vector<Eigen::Vector3d> axes = chart_axes(cells);
  assign_owners(grid, axes);
  for (std::size_t k = 0; k < axes.size(); ++k) mesh_chart(mesh, grid, valid, axes[k], static_cast<int>(k));
  return axes.size();
}

}  // namespace dentmark::ingest
