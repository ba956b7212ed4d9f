// The two graph networks: BSMS-GNN (multilevel U-Net, thesis §4.3) and MeshGraphNets (§4.4.2.2).
#pragma once

#include <torch/nn/module.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "models/graph_tensors.hpp"
#include "models/layers.hpp"

namespace bsms {

struct GraphModelOptions {
  int64_t input_size = 0;   // node input channels
  int64_t output_size = 0;  // node output channels
  int64_t latent = 128;
  // Sizes of the position fields passed to forward, e.g. {2} (mesh X) or {2, 2} (mesh X, world x).
  std::vector<int64_t> position_dims;
  // Per edge set, the position fields its edge features use: set 0 = mesh edges (e.g. {0, 1}),
  // set 1 = contact edges (e.g. {1}). Empty: one edge set using every position field.
  std::vector<std::vector<int64_t>> edge_set_fields;
  // Per edge set, an optional stretch channel (layers.hpp); missing entries: none.
  std::vector<EdgeStretch> edge_set_stretch;
  int num_levels = 1;              // BSMS: levels of the multilevel graph (>= 1)
  int message_passing_steps = 15;  // MeshGraphNets
  // BSMS: message-passing blocks on each level on the way down, at the bottom and on each level
  // on the way up (the original implementation's MP times per level); >= 1.
  int mp_per_level = 1;
  // BSMS: blocks per level, one entry per level (level k's blocks on the way down and up; the
  // last entry: the bottom), overriding mp_per_level; empty = mp_per_level on every level.
  std::vector<int> mp_per_level_list;
  // Edge features standardised per channel, one normalizer per level and edge set (MGN: level 0),
  // with statistics accumulated like the node normalizer's (accumulate_edge_statistics), as
  // MeshGraphNets' reference does; off: the raw features.
  bool edge_normalizer = false;
};

// Common interface: node inputs (normalised) to node outputs (normalised) on a graph hierarchy.
class GraphModel : public torch::nn::Module {
 public:
  explicit GraphModel(GraphModelOptions options);
  // nodes [N, input_size] float32; positions[f] [N, position_dims[f]] float32 (no gradient is
  // taken through them); graph: N = graph.num_nodes(0), e.g. a merge_multilevel_tensors() batch.
  // Edge set s of each level is graph.edge_sets[level][s]; sets the model has but the graph lacks
  // count as empty (e.g. a frame without contacts). Returns [N, output_size].
  virtual torch::Tensor forward(const torch::Tensor& nodes,
                                const std::vector<torch::Tensor>& positions,
                                const MultilevelTensors& graph) = 0;
  const GraphModelOptions& options() const { return options_; }
  // Adds the edge features of `graph` at `positions` (as forward takes them) to the edge
  // normalizers' statistics; a no-op without edge normalizers. No gradient.
  void accumulate_edge_statistics(const std::vector<torch::Tensor>& positions,
                                  const MultilevelTensors& graph);
  // The edge normalizers' sums (Normalizer::sums), level by level and set by set; empty without.
  std::vector<torch::Tensor> edge_normalizer_sums();
  // kProjection (default): fused per-node projection kernels. kConcat: every MLP evaluated with
  // plain LibTorch ops and concatenated edge inputs, as the reference implementation does (same
  // parameters; for tests and benchmarks).
  void set_edge_mlp_mode(EdgeMlpMode mode) { mode_ = mode; }

 protected:
  int64_t edge_feature_size(size_t set) const;
  size_t num_edge_sets() const { return options_.edge_set_fields.size(); }
  EdgeStretch stretch(size_t set) const {
    return set < options_.edge_set_stretch.size() ? options_.edge_set_stretch[set] : EdgeStretch{};
  }
  // Edge index `set` of `level`, or an empty set when the graph has fewer sets.
  static EdgeIndex edge_set(const MultilevelTensors& graph, int level, size_t set);
  // mlp.forward, or mlp.forward_reference in EdgeMlpMode::kConcat.
  torch::Tensor run_mlp(Mlp& mlp, const torch::Tensor& x) const;
  void check_inputs(const torch::Tensor& nodes, const std::vector<torch::Tensor>& positions,
                    const MultilevelTensors& graph) const;
  // Raw edge features [level][set] (and the edge indices) of the levels the model reads.
  virtual void edge_inputs(const std::vector<torch::Tensor>& positions,
                           const MultilevelTensors& graph, std::vector<std::vector<EdgeIndex>>* idx,
                           std::vector<std::vector<torch::Tensor>>* feats) const = 0;
  // Registers one edge normalizer per level and set when options_.edge_normalizer is on.
  void make_edge_normalizers(int levels);
  // Features of `set` at `level`, standardised by its normalizer (as given without one, or
  // while it has seen no edge: a set empty in every normaliser batch stays raw).
  torch::Tensor normalize_edges(int level, size_t set, const torch::Tensor& features) const;

  GraphModelOptions options_;
  std::vector<std::vector<std::shared_ptr<Normalizer>>> edge_norms_;  // [level][set]
  EdgeMlpMode mode_ = EdgeMlpMode::kProjection;
};

// BSMS-GNN: encoder at level 0, mp_per_level message passings per level on the way down, as many
// at the bottom and per level on the way up with skip additions, decoder. Transitions are
// non-parametric (models/graph_ops.hpp); coarse positions are the finer positions moved down by the
// transition.
class BsmsGnn : public GraphModel {
 public:
  explicit BsmsGnn(GraphModelOptions options);
  torch::Tensor forward(const torch::Tensor& nodes, const std::vector<torch::Tensor>& positions,
                        const MultilevelTensors& graph) override;

 private:
  void edge_inputs(const std::vector<torch::Tensor>& positions, const MultilevelTensors& graph,
                   std::vector<std::vector<EdgeIndex>>* idx,
                   std::vector<std::vector<torch::Tensor>>* feats) const override;
  std::shared_ptr<Mlp> encoder_, decoder_;
  // down_[k], up_[k]: the blocks of level k; bottom_: those of the coarsest level.
  std::vector<std::vector<std::shared_ptr<MessagePassing>>> down_, up_;
  std::vector<std::shared_ptr<MessagePassing>> bottom_;
};

// One MeshGraphNets step: edge latents e_s += f_s([e_s, v_i, v_j]); v += f_V([v, Σ Δe¹, …]).
class EdgeLatentBlock : public torch::nn::Module {
 public:
  EdgeLatentBlock(int64_t latent, size_t num_sets);
  // v [N, L]; latents[s] [E_s, L] updated in place of the vector; returns the new v [N, L].
  torch::Tensor forward(const torch::Tensor& v, std::vector<torch::Tensor>& latents,
                        const std::vector<const EdgeIndex*>& edges, EdgeMlpMode mode);

 private:
  std::vector<std::shared_ptr<Mlp>> edge_mlps_;
  std::shared_ptr<Mlp> node_mlp_;
};

// MeshGraphNets on level 0 of the graph: node and edge encoders, message_passing_steps blocks
// carrying edge latents with residuals, decoder.
class MeshGraphNets : public GraphModel {
 public:
  explicit MeshGraphNets(GraphModelOptions options);
  torch::Tensor forward(const torch::Tensor& nodes, const std::vector<torch::Tensor>& positions,
                        const MultilevelTensors& graph) override;

 private:
  void edge_inputs(const std::vector<torch::Tensor>& positions, const MultilevelTensors& graph,
                   std::vector<std::vector<EdgeIndex>>* idx,
                   std::vector<std::vector<torch::Tensor>>* feats) const override;
  std::shared_ptr<Mlp> node_encoder_, decoder_;
  std::vector<std::shared_ptr<Mlp>> edge_encoders_;
  std::vector<std::shared_ptr<EdgeLatentBlock>> blocks_;
};

}  // namespace bsms
