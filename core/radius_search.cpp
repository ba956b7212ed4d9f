#include "core/radius_search.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "core/error.hpp"

namespace bsms {

namespace {

void check_finite(const RowMatrixXd& points) {
  const int64_t n = points.rows();
  const int dim = static_cast<int>(points.cols());
  for (int64_t i = 0; i < n; ++i)
    for (int c = 0; c < dim; ++c)
      if (!std::isfinite(points(i, c)))
        throw InputError("radius search: node " + std::to_string(i) + " has the coordinate " +
                         std::to_string(points(i, c)) + " on axis " + std::to_string(c) +
                         " (positions must be finite)");
}

// Cells of side >= `radius`: neighbours lie in the 3^dim surrounding cells. Nodes are sorted by
// a cell key so each cell is a contiguous run, found in a table of run starts when the grid has
// few cells for its nodes, else by binary search.
struct CellGrid {
  int64_t n = 0;
  Eigen::RowVectorXd lo;
  double side[3] = {0, 0, 0};
  int64_t extent[3] = {1, 1, 1};
  std::vector<int64_t> cell;                       // [N, 3] cell indices of each node
  std::vector<std::pair<int64_t, int64_t>> keyed;  // (key, node), sorted
  bool table = false;
  std::vector<int64_t> start;  // keyed[start[k] .. start[k + 1]) have key k

  int64_t cell_of(double x, int c) const {
    const double k = std::floor((x / 2 - lo(c) / 2) / side[c] * 2);
    return static_cast<int64_t>(std::min(std::max(k, 0.0), static_cast<double>(extent[c] - 1)));
  }
  int64_t key_of(const int64_t* ijk) const {
    return (ijk[2] * extent[1] + ijk[1]) * extent[0] + ijk[0];
  }
  // The run keyed[first .. last) of the nodes in the cell `key`.
  std::pair<int64_t, int64_t> run_of(int64_t key) const {
    if (table) return {start[key], start[key + 1]};
    auto first = std::lower_bound(keyed.begin(), keyed.end(), std::make_pair(key, int64_t{-1})) -
                 keyed.begin();
    int64_t last = first;
    while (last < n && keyed[last].first == key) ++last;
    return {first, last};
  }
};

// Sizes the cells for finite `points` (at least one) and sorts the nodes into them.
CellGrid make_grid(const RowMatrixXd& points, double radius) {
  const int64_t n = points.rows();
  const int dim = static_cast<int>(points.cols());
  CellGrid grid;
  grid.n = n;
  grid.lo = points.colwise().minCoeff();
  const Eigen::RowVectorXd hi = points.colwise().maxCoeff();
  // Far-apart points (or a tiny radius) would need more cells per axis than an int64 key holds:
  // such an axis gets wider cells (side >= radius keeps the 3^dim neighbourhood exact), so every
  // cell index below is a small non-negative integer and the casts are defined.
  const double max_cells = dim == 1 ? 0x1p40 : dim == 2 ? 0x1p30 : 0x1p20;
  for (double& side : grid.side) side = radius;
  grid.cell.assign(n * 3, 0);
  for (int c = 0; c < dim; ++c) {
    double& side = grid.side[c];
    // hi/2 - lo/2 cannot overflow where hi - lo could (coordinates near the double maximum).
    const double half_range = hi(c) / 2 - grid.lo(c) / 2;
    side = std::max(radius, 2.0 * (half_range / max_cells));
    if (!std::isfinite(side)) side = std::numeric_limits<double>::max();
    grid.extent[c] =
        static_cast<int64_t>(std::min(max_cells, std::floor(half_range / side * 2))) + 1;
  }
  grid.keyed.resize(n);
  for (int64_t i = 0; i < n; ++i) {
    for (int c = 0; c < dim; ++c) grid.cell[3 * i + c] = grid.cell_of(points(i, c), c);
    grid.keyed[i] = {grid.key_of(&grid.cell[3 * i]), i};
  }
  std::sort(grid.keyed.begin(), grid.keyed.end());
  // extent[c] <= max_cells + 1, so the product fits an int64; compare in double first.
  const int64_t* extent = grid.extent;
  const double cells_d = static_cast<double>(extent[0]) * static_cast<double>(extent[1]) *
                         static_cast<double>(extent[2]);
  grid.table = cells_d <= 8.0 * static_cast<double>(n) + 4096.0;
  if (grid.table) {
    const int64_t cells = extent[0] * extent[1] * extent[2];
    grid.start.assign(cells + 1, 0);
    for (const auto& kv : grid.keyed) ++grid.start[kv.first + 1];
    for (int64_t k = 0; k < cells; ++k) grid.start[k + 1] += grid.start[k];
  }
  return grid;
}

// found[i]: the neighbours j of node i that pass the filters, ascending.
std::vector<std::vector<int64_t>> find_neighbours(const RowMatrixXd& points, double radius,
                                                  const CellGrid& grid, const CsrGraph* exclude,
                                                  const PairFilter& keep) {
  const int64_t n = points.rows();
  const int dim = static_cast<int>(points.cols());
  const double r2 = radius * radius;
  std::vector<std::vector<int64_t>> found(n);
#pragma omp parallel for schedule(dynamic, 64)
  for (int64_t i = 0; i < n; ++i) {
    const int64_t* ci = &grid.cell[3 * i];
    auto& mine = found[i];
    int64_t lo3[3] = {0, 0, 0}, hi3[3] = {0, 0, 0};
    for (int c = 0; c < dim; ++c) {
      lo3[c] = std::max<int64_t>(ci[c] - 1, 0);
      hi3[c] = std::min<int64_t>(ci[c] + 1, grid.extent[c] - 1);
    }
    int64_t q[3];
    for (q[2] = lo3[2]; q[2] <= hi3[2]; ++q[2])
      for (q[1] = lo3[1]; q[1] <= hi3[1]; ++q[1])
        for (q[0] = lo3[0]; q[0] <= hi3[0]; ++q[0]) {
          const auto [first, last] = grid.run_of(grid.key_of(q));
          for (int64_t m = first; m < last; ++m) {
            const int64_t j = grid.keyed[m].second;
            if (j == i) continue;
            double d2 = 0;
            for (int c = 0; c < dim; ++c) {
              const double d = points(i, c) - points(j, c);
              d2 += d * d;
            }
            if (d2 >= r2) continue;
            if (keep && !keep(i, j)) continue;
            if (exclude && std::binary_search(exclude->begin(i), exclude->end(i), j)) continue;
            mine.push_back(j);
          }
        }
    std::sort(mine.begin(), mine.end());
  }
  return found;
}

}  // namespace

EdgeList radius_pairs(const RowMatrixXd& points, double radius, const CsrGraph* exclude,
                      const PairFilter& keep) {
  const int64_t n = points.rows();
  if (!(radius > 0) || !std::isfinite(radius))
    throw std::invalid_argument("radius_pairs: radius must be positive and finite");
  if (exclude && exclude->num_nodes != n)
    throw std::invalid_argument("radius_pairs: exclusion graph has another node count");
  EdgeList out;
  if (n == 0) return out;
  check_finite(points);
  const std::vector<std::vector<int64_t>> found =
      find_neighbours(points, radius, make_grid(points, radius), exclude, keep);
  size_t total = 0;
  for (const auto& f : found) total += f.size();
  out.data.reserve(2 * total);
  for (int64_t i = 0; i < n; ++i)
    for (int64_t j : found[i]) {
      out.data.push_back(i);
      out.data.push_back(j);
    }
  return out;
}

}  // namespace bsms
