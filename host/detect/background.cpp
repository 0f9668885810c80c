#include "background.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <utility>
#include <vector>

#include "dentmark/common/nth_smallest.h"
#include "dentmark/host/ingest/units.h"
#include "threads.h"

namespace dentmark::detect {
namespace {

constexpr double kCell = 0.016;       // side of the cells the surface is split in (m)
constexpr double kLargePiece = 0.25;  // of the largest piece's size: a candidate for the panel
constexpr double kSmallPanel = 0.1;   // ... or this much, if it stands before the largest
constexpr double kMinArea = 0.002;    // m², ~45 x 45 mm: smaller pieces always stay
constexpr double kOffShape = 0.05;    // median distance from the panel's shape (m)

// The leaves of one cell (a run in key order) and their area-weighted sums.
struct Cell {
  std::uint64_t key = 0;  // the cell's Morton code (the leaves' keys without their low bits)
  std::size_t first = 0, last = 0;
  double area = 0.0, u = 0.0, v = 0.0, w = 0.0;  // Σ a, Σ a (u, v, w) in map coordinates
  double view = 0.0;                             // Σ a / r²: the solid angle the sensor sees it in
};

// The cells of leaves [b, e) in `box`, in key order.
std::vector<Cell> cells_of(const LinearOctree& tree, const HeightMap& frame, const Box& box, int shift,
                           std::size_t b, std::size_t e) {
  std::vector<Cell> cells;
  const auto& leaves = tree.leaves();
  for (std::size_t i = b; i < e; ++i) {
    const OctreeLeaf& l = leaves[i];
    if (!(l.area > 0.0f) || (l.centroid.array() < box.lo.array()).any() ||
        (l.centroid.array() > box.hi.array()).any())
      continue;
    const std::uint64_t key = l.key >> shift;
    if (cells.empty() || cells.back().key != key) cells.push_back({key, i, i});
    Cell& c = cells.back();
    // Σ a x in the scan's frame here; into the map's once per cell below (it is linear).
    c.last = i + 1, c.area += l.area,
    c.view += l.area / std::max(1e-6, l.centroid.cast<double>().squaredNorm());
    c.u += l.area * static_cast<double>(l.centroid.x()), c.v += l.area * static_cast<double>(l.centroid.y()),
        c.w += l.area * static_cast<double>(l.centroid.z());
  }
  for (Cell& c : cells) {
    const Eigen::Vector3d q = frame.axes * (Eigen::Vector3d(c.u, c.v, c.w) - c.area * frame.origin);
    c.u = q.x(), c.v = q.y(), c.w = q.z();
  }
  return cells;
}

int find(std::vector<int>& parent, int i) {
  while (parent[static_cast<std::size_t>(i)] != i)
    i = parent[static_cast<std::size_t>(i)] =
        parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(i)])];
  return i;
}

// The least-squares quadratic w(u, v) through cell means, weighted by their area, in
// coordinates centred and scaled about the cells' extent (a plane or the mean height
// where the cells are a strip or a spot).
class Shape {
 public:
  Shape(const std::vector<Cell>& cells, const std::vector<int>& members) {
    double area = 0.0, lo_u = 1e30, hi_u = -1e30, lo_v = 1e30, hi_v = -1e30;
    for (const int m : members) {
      const Cell& c = cells[static_cast<std::size_t>(m)];
      area += c.area, cu_ += c.u, cv_ += c.v;
      lo_u = std::min(lo_u, c.u / c.area), hi_u = std::max(hi_u, c.u / c.area);
      lo_v = std::min(lo_v, c.v / c.area), hi_v = std::max(hi_v, c.v / c.area);
    }
    cu_ /= area, cv_ /= area;
    scale_ = 2.0 / std::max({hi_u - lo_u, hi_v - lo_v, 1e-3});
    Eigen::Matrix<double, 6, 6> N = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> rhs = Eigen::Matrix<double, 6, 1>::Zero();
    for (const int m : members) {
      const Cell& c = cells[static_cast<std::size_t>(m)];
      const Eigen::Matrix<double, 6, 1> x = basis(c.u / c.area, c.v / c.area);
      N += c.area * x * x.transpose();
      rhs += c.w * x;  // c.w is the area times the mean height
    }
    const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(N);
    if (ldlt.info() == Eigen::Success && ldlt.vectorD().minCoeff() > 1e-9 * N(0, 0)) {
      c_ = ldlt.solve(rhs);
      return;
    }
    const Eigen::Matrix3d N3 = N.topLeftCorner<3, 3>();
    const Eigen::LDLT<Eigen::Matrix3d> l3(N3);
    if (l3.info() == Eigen::Success && l3.vectorD().minCoeff() > 1e-9 * N(0, 0))
      c_.head<3>() = l3.solve(rhs.head<3>());
    else
      c_(0) = rhs(0) / N(0, 0);
  }
  double at(double u, double v) const { return basis(u, v).dot(c_); }

 private:
  Eigen::Matrix<double, 6, 1> basis(double u, double v) const {
    const double x = (u - cu_) * scale_, y = (v - cv_) * scale_;
    Eigen::Matrix<double, 6, 1> b;
    b << 1.0, x, y, x * x, x * y, y * y;
    return b;
  }
  double cu_ = 0.0, cv_ = 0.0, scale_ = 1.0;
  Eigen::Matrix<double, 6, 1> c_ = Eigen::Matrix<double, 6, 1>::Zero();
};

// The median over a piece's cells of their heights off `shape` (> 0: towards the
// sensor), or of their distances from it.
double median_off(const std::vector<Cell>& cells, const std::vector<int>& members, const Shape& shape,
                  bool distance) {
  std::vector<double> off;
  off.reserve(members.size());
  for (const int m : members) {
    const Cell& c = cells[static_cast<std::size_t>(m)];
    const double d = c.w / c.area - shape.at(c.u / c.area, c.v / c.area);
    off.push_back(distance ? std::abs(d) : d);
  }
  return median_in_place(off);
}

}  // namespace

namespace {

// The cells, from fixed chunks of leaves joined in order (a cell split between two
// chunks is summed back together): the same sums whatever the number of threads.
constexpr std::size_t kChunks = 64;
std::vector<Cell> joined_cells(const LinearOctree& tree, const HeightMap& frame, const Box& box, int shift) {
  const std::size_t n = tree.leaves().size();
  std::vector<std::vector<Cell>> parts(kChunks);
#pragma omp parallel for schedule(static)
  for (std::size_t p = 0; p < kChunks; ++p)
    parts[p] = cells_of(tree, frame, box, shift, n * p / kChunks, n * (p + 1) / kChunks);
  std::vector<Cell> cells;
  for (const auto& part : parts)
    for (const Cell& c : part) {
      if (!cells.empty() && cells.back().key == c.key) {
        Cell& d = cells.back();
        d.last = c.last, d.area += c.area, d.u += c.u, d.v += c.v, d.w += c.w, d.view += c.view;
      } else {
        cells.push_back(c);
      }
    }
  return cells;
}

// A connected piece of cells: its sums and its cells, in order.
struct Piece {
  double area = 0.0, w = 0.0, view = 0.0;  // Σ a, Σ a w, Σ a / r²
  std::vector<int> cells;
};

// Pieces: cells joined to the 26 around them. The pairs are found side by side; the
// pieces do not depend on the order they are joined in (each is numbered by its first
// cell, its cells listed in order).
std::vector<Piece> pieces_of(const std::vector<Cell>& cells) {
  std::vector<std::vector<std::pair<int, int>>> pairs(kChunks);
#pragma omp parallel for schedule(static)
  for (std::size_t p = 0; p < kChunks; ++p)
    for (std::size_t a = cells.size() * p / kChunks; a < cells.size() * (p + 1) / kChunks; ++a) {
      const Eigen::Vector3i at = LinearOctree::decode(cells[a].key);
      for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const Eigen::Vector3i nb = at + Eigen::Vector3i(dx, dy, dz);
            if ((nb.array() < 0).any()) continue;
            const std::uint64_t key = LinearOctree::encode(nb);
            if (key <= cells[a].key) continue;  // each pair once
            const auto it = std::lower_bound(cells.begin() + static_cast<std::ptrdiff_t>(a) + 1, cells.end(),
                                             key, [](const Cell& c, std::uint64_t k) { return c.key < k; });
            if (it != cells.end() && it->key == key)
              pairs[p].emplace_back(static_cast<int>(a), static_cast<int>(it - cells.begin()));
          }
    }
  std::vector<int> parent(cells.size());
  std::iota(parent.begin(), parent.end(), 0);
  for (const auto& part : pairs)
    for (const auto& [a, b] : part) parent[static_cast<std::size_t>(find(parent, a))] = find(parent, b);
  std::vector<Piece> pieces;
  std::vector<int> piece_of(cells.size(), -1);
  for (std::size_t a = 0; a < cells.size(); ++a) {
    const auto root = static_cast<std::size_t>(find(parent, static_cast<int>(a)));
    if (piece_of[root] < 0) {
      piece_of[root] = static_cast<int>(pieces.size());
      pieces.emplace_back();
    }
    Piece& p = pieces[static_cast<std::size_t>(piece_of[root])];
    p.area += cells[a].area, p.w += cells[a].w, p.view += cells[a].view;
    p.cells.push_back(static_cast<int>(a));
  }
  return pieces;
}

// The panel: of the pieces the sensor sees at least a quarter as large as the largest,
// the one nearest to it (w points to it). Seen from the sensor (the frame's origin), a
// wall behind the panel is larger for its distance: it counts by its solid angle. A
// wall that fills the view round a small panel can still be over four times its size
// (a 0.5 x 0.4 m panel 5 cm before a wall 1.35 m square: 0.18 of it, and the wall was
// taken for the panel and the panel left out): a piece down to a tenth of the largest
// is a candidate too where it stands before the largest's shape by more than kOffShape.
const Piece& panel_piece(const std::vector<Piece>& pieces, const std::vector<Cell>& cells,
                         const HeightMap& frame) {
  const bool from_sensor = frame.to_map(Eigen::Vector3d::Zero()).z() > 0.1;
  const auto size = [&](const Piece& p) { return from_sensor ? p.view : p.area; };
  const Piece* largest = &pieces[0];
  for (const Piece& p : pieces)
    if (size(p) > size(*largest)) largest = &p;
  const Shape largest_shape(cells, largest->cells);
  const auto candidate = [&](const Piece& p) {
    if (size(p) >= kLargePiece * size(*largest)) return true;
    return p.area >= kMinArea && size(p) >= kSmallPanel * size(*largest) &&
           median_off(cells, p.cells, largest_shape, false) > kOffShape;
  };
  const Piece* panel = nullptr;
  for (const Piece& p : pieces)
    if (candidate(p) && (!panel || p.w / p.area > panel->w / panel->area)) panel = &p;
  return *panel;
}

}  // namespace

Background find_background(const LinearOctree& tree, const HeightMap& frame, const Box& box) {
  Background out;
  const std::size_t n = tree.leaves().size();
  const int levels = std::clamp(static_cast<int>(std::lround(std::log2(kCell / tree.leaf_size()))), 1,
                                std::max(1, tree.depth()));
  const std::vector<Cell> cells = joined_cells(tree, frame, box, 3 * levels);
  const std::vector<Piece> pieces = pieces_of(cells);
  if (std::count_if(pieces.begin(), pieces.end(), [](const Piece& p) { return p.area >= kMinArea; }) < 2)
    return out;  // one surface (and specks): the common case
  const Piece& panel = panel_piece(pieces, cells, frame);
  const Shape shape(cells, panel.cells);
  // Every other piece of some size that stands off the panel's shape is background.
  for (const Piece& p : pieces) {
    if (&p == &panel || p.area < kMinArea || median_off(cells, p.cells, shape, true) <= kOffShape) continue;
    if (out.leaf.empty()) out.leaf.assign(n, 0);
    for (const int m : p.cells) {
      const Cell& c = cells[static_cast<std::size_t>(m)];
      std::fill(out.leaf.begin() + static_cast<std::ptrdiff_t>(c.first),
                out.leaf.begin() + static_cast<std::ptrdiff_t>(c.last), 1);
      out.area += c.area;
    }
  }
  return out;
}

double panel_spacing(const ingest::MeshView& mesh, const LinearOctree& tree,
                     const std::vector<std::uint8_t>& background_leaf) {
  const auto& leaves = tree.leaves();
  return ingest::point_spacing(mesh, [&](std::size_t t) {
    const std::uint64_t key = tree.triangle_key(mesh, t);
    const auto leaf = std::lower_bound(leaves.begin(), leaves.end(), key,
                                       [](const OctreeLeaf& l, std::uint64_t k) { return l.key < k; });
    return leaf != leaves.end() && leaf->key == key &&
           !background_leaf[static_cast<std::size_t>(leaf - leaves.begin())];
  });
}

}  // namespace dentmark::detect
