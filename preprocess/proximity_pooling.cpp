#include "preprocess/proximity_pooling.hpp"

#include <array>
#include <cmath>
#include <map>
#include <string>
#include <utility>

#include "core/error.hpp"

namespace bsms {
namespace {

// Cell coordinates beyond this would lose integer precision in double.
constexpr double kMaxCellCoordinate = 1e15;

using CellKey = std::array<int64_t, 3>;  // unused axes stay 0
using CellIds = std::map<CellKey, int64_t>;

// Edges between distinct occupied cells at most one cell apart per axis: cells in id order, for
// each the offsets in {-1, 0, 1}^dim with axis 0 varying fastest.
EdgeList neighbour_edges(const CellIds& cell_id, int64_t dim) {
  int64_t num_offsets = 1;
  for (int64_t a = 0; a < dim; ++a) num_offsets *= 3;
  EdgeList edges;
  for (const auto& [key, c] : cell_id) {
    for (int64_t o = 0; o < num_offsets; ++o) {
      CellKey neighbour = key;
      bool self = true;
      for (int64_t a = 0, rest = o; a < dim; ++a, rest /= 3) {
        const int64_t step = rest % 3 - 1;
        neighbour[a] += step;
        self = self && step == 0;
      }
      if (self) continue;
      auto it = cell_id.find(neighbour);
      if (it != cell_id.end()) edges.data.insert(edges.data.end(), {c, it->second});
    }
  }
  return edges;
}

// One coarsening step: cells of size `cell` over the fine positions [n, dim].
ProximityLevel coarsen_by_grid(const RowMatrixXd& fine, double cell) {
  const int64_t n = fine.rows(), dim = fine.cols();
  CellIds cell_id;
  std::vector<CellKey> key_of(n, CellKey{0, 0, 0});
  for (int64_t i = 0; i < n; ++i) {
    for (int64_t a = 0; a < dim; ++a) {
      key_of[i][a] = static_cast<int64_t>(std::floor(fine(i, a) / cell));
    }
    cell_id.emplace(key_of[i], 0);
  }
  int64_t nc = 0;
  for (auto& entry : cell_id) entry.second = nc++;

  ProximityLevel out;
  out.num_nodes = nc;
  out.cluster_of.resize(n);
  std::vector<int64_t> count(nc, 0);
  for (int64_t i = 0; i < n; ++i) {
    out.cluster_of[i] = cell_id[key_of[i]];
    ++count[out.cluster_of[i]];
  }
  // Members of each cell, fine nodes ascending; positions summed in that order.
  out.member_offsets.assign(nc + 1, 0);
  for (int64_t c = 0; c < nc; ++c) out.member_offsets[c + 1] = out.member_offsets[c] + count[c];
  std::vector<int64_t> next(out.member_offsets.begin(), out.member_offsets.end() - 1);
  out.members.resize(n);
  out.member_weight.resize(n);
  out.positions = RowMatrixXd::Zero(nc, dim);
  for (int64_t i = 0; i < n; ++i) {
    const int64_t c = out.cluster_of[i];
    out.members[next[c]] = i;
    out.member_weight[next[c]++] = 1.0f / static_cast<float>(count[c]);
    for (int64_t a = 0; a < dim; ++a) out.positions(c, a) += fine(i, a);
  }
  for (int64_t c = 0; c < nc; ++c) {
    for (int64_t a = 0; a < dim; ++a) out.positions(c, a) /= static_cast<double>(count[c]);
  }
  out.edges = neighbour_edges(cell_id, dim);
  return out;
}

void check_inputs(const RowMatrixXd& positions, const EdgeList& level0_edges, int num_levels,
                  double cell_size) {
  const std::string where = "proximity hierarchy: ";
  const int64_t n = positions.rows(), dim = positions.cols();
  if (n < 1 || dim < 1 || dim > 3) {
    throw InputError(where + "positions must be [N, d] with N >= 1 and d in 1..3, got [" +
                     std::to_string(n) + ", " + std::to_string(dim) + "]");
  }
  if (num_levels < 1) {
    throw InputError(where + "num_levels must be >= 1, got " + std::to_string(num_levels));
  }
  if (!(cell_size > 0.0) || !std::isfinite(cell_size)) {
    throw InputError(where + "cell_size must be a positive finite number, got " +
                     std::to_string(cell_size));
  }
  for (int64_t i = 0; i < n; ++i) {
    for (int64_t a = 0; a < dim; ++a) {
      if (!std::isfinite(positions(i, a))) {
        throw InputError(where + "position of node " + std::to_string(i) + " is not finite");
      }
      if (std::abs(positions(i, a)) / cell_size > kMaxCellCoordinate) {
        throw InputError(where + "node " + std::to_string(i) + " lies more than 1e15 cells (" +
                         std::to_string(cell_size) + ") from the origin");
      }
    }
  }
  for (int64_t e = 0; e < level0_edges.size(); ++e) {
    const int64_t s = level0_edges.sender(e), r = level0_edges.receiver(e);
    if (s < 0 || s >= n || r < 0 || r >= n) {
      throw InputError(where + "level-0 edge " + std::to_string(e) + " (" + std::to_string(s) +
                       ", " + std::to_string(r) + ") outside [0, " + std::to_string(n) + ")");
    }
  }
}

}  // namespace

ProximityMultilevelGraph build_proximity_multilevel_graph(const RowMatrixXd& positions,
                                                          const EdgeList& level0_edges,
                                                          int num_levels, double cell_size) {
  check_inputs(positions, level0_edges, num_levels, cell_size);
  ProximityMultilevelGraph graph;
  ProximityLevel level0;
  level0.num_nodes = positions.rows();
  level0.edges = level0_edges;
  level0.positions = positions;
  graph.levels.push_back(std::move(level0));
  for (int k = 1; k < num_levels; ++k) {
    graph.levels.push_back(
        coarsen_by_grid(graph.levels.back().positions, std::ldexp(cell_size, k - 1)));
  }
  return graph;
}

}  // namespace bsms
