#include "models/proximity_multilevel.hpp"

#include <array>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "core/error.hpp"

namespace bsms {
namespace {

// Cell coordinates beyond this would lose integer precision in double.
constexpr double kMaxCellCoordinate = 1e15;

using CellKey = std::array<int64_t, 3>;  // unused axes stay 0

torch::Tensor int64_tensor(const std::vector<int64_t>& values) {
  return torch::tensor(values, torch::kInt64).reshape({static_cast<int64_t>(values.size())});
}

torch::Tensor float_tensor(const std::vector<float>& values) {
  return torch::tensor(values, torch::kFloat32).reshape({static_cast<int64_t>(values.size())});
}

// One coarsening step: cells of size `cell` over the fine positions [n, dim] (row-major).
struct GridLevel {
  std::vector<double> positions;  // [nc, dim], mean of the members
  LevelTransition transition;
  EdgeIndex edges;
};

GridLevel coarsen_by_grid(const std::vector<double>& fine, int64_t n, int64_t dim, double cell) {
  std::map<CellKey, int64_t> cell_id;
  std::vector<CellKey> key_of(n, CellKey{0, 0, 0});
  for (int64_t i = 0; i < n; ++i) {
    for (int64_t a = 0; a < dim; ++a) {
      key_of[i][a] = static_cast<int64_t>(std::floor(fine[i * dim + a] / cell));
    }
    cell_id.emplace(key_of[i], 0);
  }
  int64_t nc = 0;
  for (auto& entry : cell_id) entry.second = nc++;

  // Members of each cell, fine nodes ascending.
  std::vector<int64_t> coarse_of(n), count(nc, 0);
  for (int64_t i = 0; i < n; ++i) {
    coarse_of[i] = cell_id[key_of[i]];
    ++count[coarse_of[i]];
  }
  std::vector<int64_t> down_offsets(nc + 1, 0);
  for (int64_t c = 0; c < nc; ++c) down_offsets[c + 1] = down_offsets[c] + count[c];
  std::vector<int64_t> down_columns(n), next(down_offsets.begin(), down_offsets.end() - 1);
  std::vector<float> down_values(n);
  GridLevel out;
  out.positions.assign(nc * dim, 0.0);
  for (int64_t i = 0; i < n; ++i) {
    const int64_t c = coarse_of[i];
    down_columns[next[c]] = i;
    down_values[next[c]++] = 1.0f / static_cast<float>(count[c]);
    for (int64_t a = 0; a < dim; ++a) out.positions[c * dim + a] += fine[i * dim + a];
  }
  for (int64_t c = 0; c < nc; ++c) {
    for (int64_t a = 0; a < dim; ++a) out.positions[c * dim + a] /= static_cast<double>(count[c]);
  }
  std::vector<int64_t> up_offsets(n + 1);
  for (int64_t i = 0; i <= n; ++i) up_offsets[i] = i;

  LevelTransition& t = out.transition;
  t.fine_nodes = n;
  t.coarse_nodes = nc;
  t.down_offsets = int64_tensor(down_offsets);
  t.down_columns = int64_tensor(down_columns);
  t.down_values = float_tensor(down_values);
  t.up_offsets = int64_tensor(up_offsets);
  t.up_columns = int64_tensor(coarse_of);
  t.up_values = torch::ones({n}, torch::kFloat32);
  t.up_is_down_transpose = false;

  // Neighbouring occupied cells: offsets in {-1, 0, 1}^dim without the zero offset. Cells are
  // visited in id order and offsets lexicographically, so edges come sorted by (sender, receiver).
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
  out.edges = EdgeIndex::from_edge_list(edges, nc);
  return out;
}

}  // namespace

MultilevelTensors make_proximity_multilevel(const torch::Tensor& positions,
                                            const torch::Tensor& level0_edges, int num_levels,
                                            double cell_size) {
  const std::string where = "proximity hierarchy: ";
  if (positions.dim() != 2 || positions.size(0) < 1 || positions.size(1) < 1 ||
      positions.size(1) > 3 || !positions.is_floating_point()) {
    throw InputError(where + "positions must be a floating-point [N, d] tensor with N >= 1 and " +
                     "d in 1..3, got " + std::string(c10::toString(positions.scalar_type())) + " " +
                     std::string(c10::str(positions.sizes())));
  }
  if (level0_edges.scalar_type() != torch::kInt64) {
    throw InputError(where + "level-0 edges must be an int64 [E, 2] tensor, got " +
                     std::string(c10::toString(level0_edges.scalar_type())));
  }
  if (num_levels < 1) {
    throw InputError(where + "num_levels must be >= 1, got " + std::to_string(num_levels));
  }
  if (!(cell_size > 0.0) || !std::isfinite(cell_size)) {
    throw InputError(where + "cell_size must be a positive finite number, got " +
                     std::to_string(cell_size));
  }
  const auto p = positions.to(torch::kFloat64).contiguous();
  const int64_t n = p.size(0), dim = p.size(1);
  std::vector<double> pos(p.data_ptr<double>(), p.data_ptr<double>() + n * dim);
  for (int64_t q = 0; q < n * dim; ++q) {
    if (!std::isfinite(pos[q])) {
      throw InputError(where + "position of node " + std::to_string(q / dim) + " is not finite");
    }
    if (std::abs(pos[q]) / cell_size > kMaxCellCoordinate) {
      throw InputError(where + "node " + std::to_string(q / dim) + " lies more than 1e15 cells (" +
                       std::to_string(cell_size) + ") from the origin");
    }
  }

  MultilevelTensors h;
  h.edge_sets.push_back({EdgeIndex::from_pairs(level0_edges, n)});
  h.node_offsets.push_back({0, n});
  h.transitions.emplace_back();  // level 0 has no transition (graph_tensors.hpp)
  int64_t nodes = n;
  for (int k = 1; k < num_levels; ++k) {
    GridLevel level = coarsen_by_grid(pos, nodes, dim, std::ldexp(cell_size, k - 1));
    nodes = level.transition.coarse_nodes;
    pos = std::move(level.positions);
    h.edge_sets.push_back({std::move(level.edges)});
    h.transitions.push_back(std::move(level.transition));
    h.node_offsets.push_back({0, nodes});
  }
  return h;
}

}  // namespace bsms
