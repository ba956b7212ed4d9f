// A multilevel graph in index form (preprocess/: bi-stride, multilevel_graph.hpp; proximity,
// proximity_pooling.hpp) as the tensors the models run on (models/graph_tensors.hpp): the one
// place where preprocess/ meets models/, so that models/ depends on core/ only.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "models/graph_tensors.hpp"
#include "preprocess/multilevel_graph.hpp"
#include "preprocess/proximity_pooling.hpp"

namespace bsms {

// Tensors of a multilevel graph; max_levels > 0 keeps only the finest max_levels levels.
// InputError when the graph has no levels or a level's pooled nodes or down weights do not fit.
MultilevelTensors make_multilevel_tensors(const MultilevelGraph& graph, int max_levels = 0);

// Tensors of a proximity multilevel graph: level 0's edges as given, transition k's down matrix
// D [N_k, N_(k-1)] = the member weights of each cell, its up matrix the cell's value given to each
// member (weight 1), which is not Dᵀ (up_is_down_transpose = false). One graph (node_offsets
// {0, N_k}), ready for merge_multilevel_tensors(). InputError when the graph has no levels or a
// level's pooling does not fit its sizes.
MultilevelTensors make_multilevel_tensors(const ProximityMultilevelGraph& graph);

// Builds each mesh's tensors once and keeps them (and the last batch merged) for later steps.
class MultilevelTensorCache {
 public:
  explicit MultilevelTensorCache(int max_levels = 0) : max_levels_(max_levels) {}
  const MultilevelTensors& get(const std::string& key, const MultilevelGraph& graph);
  bool contains(const std::string& key) const { return single_.count(key) != 0; }
  // The merged batch of cached meshes (all keys must have been added with get()).
  const MultilevelTensors& batch(const std::vector<std::string>& keys);

 private:
  int max_levels_;
  std::map<std::string, std::shared_ptr<MultilevelTensors>> single_;
  std::vector<std::string> last_batch_keys_;
  MultilevelTensors last_batch_;
};

}  // namespace bsms
