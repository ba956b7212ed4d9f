#include "pipeline/graphs/multilevel_tensors.hpp"

#include <algorithm>
#include <numeric>
#include <string>

#include "core/error.hpp"

namespace bsms {

MultilevelTensors make_multilevel_tensors(const MultilevelGraph& graph, int max_levels) {
  int levels = graph.num_levels();
  if (levels == 0) throw InputError("multilevel graph: no levels");
  if (max_levels > 0) levels = std::min(levels, max_levels);
  MultilevelTensors h;
  for (int k = 0; k < levels; ++k) {
    const GraphLevel& level = graph.levels[k];
    h.edge_sets.push_back({EdgeIndex::from_csr(level.graph)});
    h.node_offsets.push_back({0, level.num_nodes()});
    h.transitions.push_back(k > 0
                                ? LevelTransition::from_down_weights(
                                      graph.levels[k - 1].graph, level.pooled, level.down_weight, k)
                                : LevelTransition{});
  }
  return h;
}

namespace {

torch::Tensor int64_tensor(const std::vector<int64_t>& values) {
  return torch::tensor(values, torch::kInt64).reshape({static_cast<int64_t>(values.size())});
}

torch::Tensor float_tensor(const std::vector<float>& values) {
  return torch::tensor(values, torch::kFloat32).reshape({static_cast<int64_t>(values.size())});
}

// The transition from a level of `fine_nodes` nodes to `level`, pooled by cells.
LevelTransition cell_transition(int64_t fine_nodes, const ProximityLevel& level, int k) {
  const int64_t n = fine_nodes, nc = level.num_nodes;
  if (static_cast<int64_t>(level.cluster_of.size()) != n ||
      static_cast<int64_t>(level.member_offsets.size()) != nc + 1 ||
      static_cast<int64_t>(level.members.size()) != n ||
      static_cast<int64_t>(level.member_weight.size()) != n) {
    throw InputError("proximity multilevel graph: level " + std::to_string(k) +
                     " pools its cells from " + std::to_string(level.cluster_of.size()) +
                     " nodes, level " + std::to_string(k - 1) + " has " + std::to_string(n));
  }
  std::vector<int64_t> up_offsets(n + 1);
  std::iota(up_offsets.begin(), up_offsets.end(), int64_t{0});
  LevelTransition t;
  t.fine_nodes = n;
  t.coarse_nodes = nc;
  t.down_offsets = int64_tensor(level.member_offsets);
  t.down_columns = int64_tensor(level.members);
  t.down_values = float_tensor(level.member_weight);
  t.up_offsets = int64_tensor(up_offsets);
  t.up_columns = int64_tensor(level.cluster_of);
  t.up_values = torch::ones({n}, torch::kFloat32);
  t.up_is_down_transpose = false;
  return t;
}

}  // namespace

MultilevelTensors make_multilevel_tensors(const ProximityMultilevelGraph& graph) {
  if (graph.num_levels() == 0) throw InputError("proximity multilevel graph: no levels");
  MultilevelTensors h;
  for (int k = 0; k < graph.num_levels(); ++k) {
    const ProximityLevel& level = graph.levels[k];
    h.edge_sets.push_back({EdgeIndex::from_edge_list(level.edges, level.num_nodes)});
    h.node_offsets.push_back({0, level.num_nodes});
    h.transitions.push_back(k > 0 ? cell_transition(graph.levels[k - 1].num_nodes, level, k)
                                  : LevelTransition{});
  }
  return h;
}

const MultilevelTensors& MultilevelTensorCache::get(const std::string& key,
                                                    const MultilevelGraph& graph) {
  auto it = single_.find(key);
  if (it == single_.end()) {
    it = single_
             .emplace(key, std::make_shared<MultilevelTensors>(
                               make_multilevel_tensors(graph, max_levels_)))
             .first;
  }
  return *it->second;
}

const MultilevelTensors& MultilevelTensorCache::batch(const std::vector<std::string>& keys) {
  if (keys == last_batch_keys_ && !keys.empty()) return last_batch_;
  std::vector<const MultilevelTensors*> parts;
  for (const auto& key : keys) {
    auto it = single_.find(key);
    if (it == single_.end()) throw InputError("graph batch: mesh '" + key + "' is not cached");
    parts.push_back(it->second.get());
  }
  last_batch_ = merge_multilevel_tensors(parts);
  last_batch_keys_ = keys;
  return last_batch_;
}

}  // namespace bsms
