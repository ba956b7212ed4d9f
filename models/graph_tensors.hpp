// Index tensors of (batched) multilevel graphs, precomputed once per mesh for the graph kernels.
// Built from core's CSR graphs and plain arrays only: preprocess/'s bi-stride MultilevelGraph and
// proximity graph (proximity_pooling.hpp) become MultilevelTensors in
// src/pipeline/graphs/multilevel_tensors.hpp.
#pragma once

#include <torch/types.h>

#include <cstdint>
#include <vector>

#include "core/graph.hpp"

namespace bsms {

// One directed edge set with edges grouped both by sender and by receiver (stable counting sort),
// so that sums over the edges of a node are contiguous segment reductions without atomics.
struct EdgeIndex {
  int64_t num_nodes = 0;
  torch::Tensor senders;    // [E] int64
  torch::Tensor receivers;  // [E] int64
  torch::Tensor
      sender_offsets;  // [N + 1] int64: edges of sender i are sender_order[off[i]..off[i+1])
  torch::Tensor sender_order;      // [E] int64 edge ids grouped by sender
  torch::Tensor receiver_offsets;  // [N + 1] int64
  torch::Tensor receiver_order;    // [E] int64 edge ids grouped by receiver

  int64_t num_edges() const { return senders.defined() ? senders.size(0) : 0; }

  // From (sender, receiver) pairs, [E, 2] int64 (any order; duplicates allowed). InputError when
  // an index is outside [0, num_nodes).
  static EdgeIndex from_pairs(const torch::Tensor& edges, int64_t num_nodes);
  static EdgeIndex from_csr(const CsrGraph& graph);
  static EdgeIndex from_edge_list(const EdgeList& edges, int64_t num_nodes);  // InputError as above
  static EdgeIndex empty(int64_t num_nodes);
};

// Non-parametric transition between level k (fine) and k+1 (coarse), docs/design.md "Bi-stride
// multilevel building" item 6, as a sparse matrix D [N_coarse, N_fine]: D[c, i] = down_weight of
// the fine edge i -> pooled[c]. Down: v_coarse = D v_fine. Up (unpool, then reversed edges): v_fine
// = Dᵀ v_coarse. Other multilevel graphs (the proximity one, multilevel_tensors.hpp) may give an up
// matrix U [N_fine, N_coarse] that is not Dᵀ; they set up_is_down_transpose = false so that
// gradients use the true adjoints.
struct LevelTransition {
  int64_t fine_nodes = 0;
  int64_t coarse_nodes = 0;
  torch::Tensor down_offsets;  // [N_coarse + 1] int64, CSR rows of D
  torch::Tensor down_columns;  // [nnz] int64, fine node ids
  torch::Tensor down_values;   // [nnz] float32
  torch::Tensor up_offsets;    // [N_fine + 1] int64, CSR rows of Dᵀ
  torch::Tensor up_columns;    // [nnz] int64, coarse node ids
  torch::Tensor up_values;     // [nnz] float32
  bool up_is_down_transpose = true;

  // The bi-stride transition from level k-1 to level k of a multilevel graph, given as plain
  // arrays (the fields of preprocess/'s GraphLevel; models/ does not depend on preprocess/):
  // `fine` = level k-1's graph, `pooled` [N_k] its nodes kept at level k (ascending), and
  // `down_weight` [E_(k-1)] one weight per edge of `fine` in CSR order. `level` = k, for messages.
  // InputError when the sizes or indices do not fit.
  static LevelTransition from_down_weights(const CsrGraph& fine, const std::vector<int64_t>& pooled,
                                           const std::vector<float>& down_weight, int level);
};

// The tensors a model needs for one graph or a block-diagonal batch of graphs.
struct MultilevelTensors {
  std::vector<std::vector<EdgeIndex>> edge_sets;  // [level][set]; set 0 = mesh edges
  // [level]: transitions[k] joins level k - 1 (fine) and level k (coarse), the convention of
  // preprocess/ and of the multilevel file (level k holds its pooled nodes and down weights);
  // transitions[0] is empty. Size num_levels.
  std::vector<LevelTransition> transitions;
  std::vector<std::vector<int64_t>> node_offsets;  // [level][graph + 1] node range of each graph

  int num_levels() const { return static_cast<int>(edge_sets.size()); }
  int num_graphs() const;
  int64_t num_nodes(int level) const;

  // A copy with extra edge sets (e.g. contact edges) appended after the existing ones:
  // extra[level][s] is an [E, 2] int64 tensor of (sender, receiver) in this hierarchy's numbering.
  // Levels missing from `extra` get empty sets, so every level has the same number of sets.
  MultilevelTensors with_edge_sets(const std::vector<std::vector<torch::Tensor>>& extra) const;
  MultilevelTensors with_edge_sets(const std::vector<std::vector<EdgeIndex>>& extra) const;
  // One extra set per level, e.g. enhance_contact_edges_all_levels() (preprocess/).
  MultilevelTensors with_edge_sets(const std::vector<EdgeList>& per_level) const;
};

// Block-diagonal merge of several hierarchies (different meshes allowed) with the same number of
// levels; graph g's nodes follow those of graphs 0..g-1 at every level. Node features of the batch
// are torch::cat of the graphs' features along dim 0. InputError on a level-count mismatch.
MultilevelTensors merge_multilevel_tensors(const std::vector<const MultilevelTensors*>& graphs);

}  // namespace bsms
