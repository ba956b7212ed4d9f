#include "pipeline/graphs/multilevel_tensors.hpp"

#include <algorithm>

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
