#include "models/networks.hpp"

#include <ATen/ops/layer_norm.h>

#include <numeric>

#include "core/error.hpp"
#include "models/graph_ops.hpp"

namespace bsms {
namespace {

GraphModelOptions resolved(GraphModelOptions o) {
  if (o.input_size <= 0 || o.output_size <= 0 || o.latent <= 0) {
    throw InputError("graph model: input_size, output_size and latent must be positive (got " +
                     std::to_string(o.input_size) + ", " + std::to_string(o.output_size) + ", " +
                     std::to_string(o.latent) + ")");
  }
  if (o.position_dims.empty()) throw InputError("graph model: no position fields (position_dims)");
  if (o.edge_set_fields.empty()) {
    std::vector<int64_t> all(o.position_dims.size());
    std::iota(all.begin(), all.end(), 0);
    o.edge_set_fields = {all};
  }
  for (const auto& fields : o.edge_set_fields) {
    for (int64_t f : fields) {
      if (f < 0 || f >= static_cast<int64_t>(o.position_dims.size())) {
        throw InputError("graph model: edge set uses position field " + std::to_string(f) +
                         ", only " + std::to_string(o.position_dims.size()) + " exist");
      }
    }
  }
  if (o.edge_set_stretch.size() > o.edge_set_fields.size())
    throw InputError("graph model: more stretch entries than edge sets");
  for (const auto& st : o.edge_set_stretch) {
    if (!st.enabled()) continue;
    const int64_t fields = static_cast<int64_t>(o.position_dims.size());
    if (st.current < 0 || st.reference >= fields || st.current >= fields ||
        o.position_dims[st.reference] != o.position_dims[st.current] || !(st.inv_scale > 0))
      throw InputError(
          "graph model: a stretch channel needs two position fields of one size and a scale > 0");
  }
  if (o.num_levels < 1) throw InputError("graph model: num_levels must be >= 1");
  if (o.message_passing_steps < 1) {
    throw InputError("graph model: message_passing_steps must be >= 1");
  }
  return o;
}

}  // namespace

GraphModel::GraphModel(GraphModelOptions options) : options_(resolved(std::move(options))) {}

int64_t GraphModel::edge_feature_size(size_t set) const {
  int64_t size = 0;
  for (int64_t f : options_.edge_set_fields[set]) size += options_.position_dims[f] + 1;
  return size + (stretch(set).enabled() ? 1 : 0);
}

void GraphModel::make_edge_normalizers(int levels) {
  if (!options_.edge_normalizer) return;
  edge_norms_.resize(static_cast<size_t>(levels));
  for (int k = 0; k < levels; ++k)
    for (size_t s = 0; s < num_edge_sets(); ++s)
      edge_norms_[k].push_back(
          register_module("edge_normalizer_" + std::to_string(k) + "_" + std::to_string(s),
                          std::make_shared<Normalizer>(edge_feature_size(s))));
}

torch::Tensor GraphModel::normalize_edges(int level, size_t set,
                                          const torch::Tensor& features) const {
  if (edge_norms_.empty()) return features;
  const Normalizer& norm = *edge_norms_[level][set];
  return norm.empty() ? features : norm.normalize(features);
}

void GraphModel::accumulate_edge_statistics(const std::vector<torch::Tensor>& positions,
                                            const MultilevelTensors& graph) {
  if (edge_norms_.empty()) return;
  torch::NoGradGuard no_grad;
  std::vector<std::vector<EdgeIndex>> idx;
  std::vector<std::vector<torch::Tensor>> feats;
  edge_inputs(positions, graph, &idx, &feats);
  for (size_t k = 0; k < feats.size(); ++k)
    for (size_t s = 0; s < feats[k].size(); ++s)
      if (feats[k][s].size(0) > 0) edge_norms_[k][s]->accumulate(feats[k][s]);
}

std::vector<torch::Tensor> GraphModel::edge_normalizer_sums() {
  std::vector<torch::Tensor> sums;
  for (auto& level : edge_norms_)
    for (auto& norm : level)
      for (auto& t : norm->sums()) sums.push_back(t);
  return sums;
}

EdgeIndex GraphModel::edge_set(const MultilevelTensors& graph, int level, size_t set) {
  const auto& sets = graph.edge_sets[level];
  return set < sets.size() ? sets[set] : EdgeIndex::empty(graph.num_nodes(level));
}

torch::Tensor GraphModel::run_mlp(Mlp& mlp, const torch::Tensor& x) const {
  return mode_ == EdgeMlpMode::kConcat ? mlp.forward_reference(x) : mlp.forward(x);
}

void GraphModel::check_inputs(const torch::Tensor& nodes,
                              const std::vector<torch::Tensor>& positions,
                              const MultilevelTensors& graph) const {
  if (graph.num_levels() == 0) throw InputError("graph model: empty graph hierarchy");
  const int64_t n = graph.num_nodes(0);
  if (nodes.dim() != 2 || nodes.size(0) != n || nodes.size(1) != options_.input_size) {
    throw InputError("graph model: node inputs have shape " + std::string(c10::str(nodes.sizes())) +
                     ", expected [" + std::to_string(n) + ", " +
                     std::to_string(options_.input_size) + "]");
  }
  if (positions.size() != options_.position_dims.size()) {
    throw InputError("graph model: " + std::to_string(positions.size()) +
                     " position fields given, expected " +
                     std::to_string(options_.position_dims.size()));
  }
  for (size_t f = 0; f < positions.size(); ++f) {
    if (positions[f].dim() != 2 || positions[f].size(0) != n ||
        positions[f].size(1) != options_.position_dims[f]) {
      throw InputError("graph model: position field " + std::to_string(f) + " has shape " +
                       std::string(c10::str(positions[f].sizes())) + ", expected [" +
                       std::to_string(n) + ", " + std::to_string(options_.position_dims[f]) + "]");
    }
  }
  for (const auto& sets : graph.edge_sets) {
    if (sets.size() > num_edge_sets()) {
      throw InputError("graph model: graph has " + std::to_string(sets.size()) +
                       " edge sets, the model was built for " + std::to_string(num_edge_sets()));
    }
  }
}

BsmsGnn::BsmsGnn(GraphModelOptions options) : GraphModel(std::move(options)) {
  const int64_t latent = options_.latent;
  std::vector<int64_t> feature_sizes;
  for (size_t s = 0; s < num_edge_sets(); ++s) feature_sizes.push_back(edge_feature_size(s));
  encoder_ =
      register_module("encoder", std::make_shared<Mlp>(options_.input_size, latent, latent, true));
  if (options_.mp_per_level < 1) {
    throw InputError("BSMS-GNN: mp_per_level is " + std::to_string(options_.mp_per_level) +
                     ", expected >= 1");
  }
  const int levels = options_.num_levels;
  std::vector<int> counts = options_.mp_per_level_list;
  if (counts.empty()) counts.assign(static_cast<size_t>(levels), options_.mp_per_level);
  if (static_cast<int>(counts.size()) != levels) {
    throw InputError("BSMS-GNN: mp_per_level lists " + std::to_string(counts.size()) +
                     " block counts, the graph has " + std::to_string(levels) +
                     " levels (one count per level expected)");
  }
  for (int c : counts) {
    if (c < 1) {
      throw InputError("BSMS-GNN: a level's block count is " + std::to_string(c) +
                       ", expected >= 1");
    }
  }
  // Block i > 0 of a level is named <name>_<i>: models with one block per level keep the names
  // (and checkpoints) they had before the count was an option.
  auto blocks = [&](const std::string& name, int count) {
    std::vector<std::shared_ptr<MessagePassing>> out;
    for (int i = 0; i < count; ++i) {
      out.push_back(register_module(i == 0 ? name : name + "_" + std::to_string(i),
                                    std::make_shared<MessagePassing>(latent, feature_sizes)));
    }
    return out;
  };
  for (int k = 0; k + 1 < levels; ++k) {
    down_.push_back(blocks("down_" + std::to_string(k), counts[k]));
    up_.push_back(blocks("up_" + std::to_string(k), counts[k]));
  }
  bottom_ = blocks("bottom", counts.back());
  decoder_ = register_module("decoder",
                             std::make_shared<Mlp>(latent, latent, options_.output_size, false));
  make_edge_normalizers(levels);
}

void BsmsGnn::edge_inputs(const std::vector<torch::Tensor>& positions,
                          const MultilevelTensors& graph, std::vector<std::vector<EdgeIndex>>* idx,
                          std::vector<std::vector<torch::Tensor>>* feats) const {
  const int levels = options_.num_levels;
  const size_t num_sets = num_edge_sets();
  // Coarse positions: the finer positions moved down by the transition (no gradient).
  std::vector<std::vector<torch::Tensor>> level_pos(levels);
  level_pos[0] = positions;
  {
    torch::NoGradGuard no_grad;
    for (int k = 0; k + 1 < levels; ++k) {
      for (const auto& p : level_pos[k]) {
        level_pos[k + 1].push_back(transition_down(p.contiguous(), graph.transitions[k + 1]));
      }
    }
  }
  idx->assign(levels, {});
  feats->assign(levels, {});
  for (int k = 0; k < levels; ++k) {
    for (size_t s = 0; s < num_sets; ++s) {
      (*idx)[k].push_back(edge_set(graph, k, s));
      (*feats)[k].push_back(
          edge_features(level_pos[k], options_.edge_set_fields[s], (*idx)[k].back(), stretch(s)));
    }
  }
}

torch::Tensor BsmsGnn::forward(const torch::Tensor& nodes,
                               const std::vector<torch::Tensor>& positions,
                               const MultilevelTensors& graph) {
  check_inputs(nodes, positions, graph);
  const int levels = options_.num_levels;
  if (graph.num_levels() != levels) {
    throw InputError("BSMS-GNN: graph has " + std::to_string(graph.num_levels()) +
                     " levels, the model was built for " + std::to_string(levels));
  }
  std::vector<std::vector<EdgeIndex>> idx;
  std::vector<std::vector<torch::Tensor>> feats;
  edge_inputs(positions, graph, &idx, &feats);
  for (int k = 0; k < levels; ++k)
    for (size_t s = 0; s < feats[k].size(); ++s) feats[k][s] = normalize_edges(k, s, feats[k][s]);

  auto v = run_mlp(*encoder_, nodes);
  std::vector<torch::Tensor> skips;
  auto pass = [&](std::vector<std::shared_ptr<MessagePassing>>& mp_per_level_list, int k,
                  torch::Tensor x) {
    for (auto& block : mp_per_level_list) x = block->forward(x, feats[k], idx[k], mode_);
    return x;
  };
  for (int k = 0; k + 1 < levels; ++k) {
    v = pass(down_[k], k, v);
    skips.push_back(v);
    v = transition_down(v, graph.transitions[k + 1]);
  }
  v = pass(bottom_, levels - 1, v);
  for (int k = levels - 2; k >= 0; --k) {
    v = transition_up(v, graph.transitions[k + 1]);
    v = pass(up_[k], k, v) + skips[k];
  }
  return run_mlp(*decoder_, v);
}

EdgeLatentBlock::EdgeLatentBlock(int64_t latent, size_t num_sets) {
  for (size_t s = 0; s < num_sets; ++s) {
    edge_mlps_.push_back(register_module("edge_mlp_" + std::to_string(s),
                                         std::make_shared<Mlp>(3 * latent, latent, latent, true)));
  }
  node_mlp_ = register_module(
      "node_mlp",
      std::make_shared<Mlp>((1 + static_cast<int64_t>(num_sets)) * latent, latent, latent, true));
}

torch::Tensor EdgeLatentBlock::forward(const torch::Tensor& v, std::vector<torch::Tensor>& latents,
                                       const std::vector<const EdgeIndex*>& edges,
                                       EdgeMlpMode mode) {
  const int64_t latent = v.size(1);
  std::vector<torch::Tensor> node_in{v};
  for (size_t s = 0; s < edge_mlps_.size(); ++s) {
    Mlp& mlp = *edge_mlps_[s];
    const EdgeIndex& index = *edges[s];
    torch::Tensor update, summed;
    if (mode == EdgeMlpMode::kConcat) {
      update = mlp.forward_reference(torch::cat(
          {latents[s], v.index_select(0, index.senders), v.index_select(0, index.receivers)}, 1));
      summed = torch::zeros_like(v).index_add_(0, index.receivers, update);
    } else {
      const auto& w = mlp.first()->weight;  // [L, 3L]: edge, sender, receiver columns
      auto a = linear(v, w.narrow(1, latent, latent), {}, false);
      auto b = linear(v, w.narrow(1, 2 * latent, latent), {}, false);
      if (!torch::GradMode::is_enabled()) {
        // Inference: the edge MLP, its LayerNorm, the residual and the sum over receivers in
        // cache-sized tiles of edges (same math; only the LayerNorm output is written).
        torch::Tensor next;
        node_in.push_back(edge_latent_update(latents[s], w.narrow(1, 0, latent), mlp.first()->bias,
                                             a, b, mlp.second()->weight, mlp.second()->bias,
                                             mlp.third()->weight, mlp.third()->bias, index, next));
        latents[s] = next;
        continue;
      }
      auto base = linear(latents[s], w.narrow(1, 0, latent), {}, false);
      auto none = torch::empty({index.num_edges(), 0});
      auto hidden = mlp.tail(
          edge_first_layer(base, none, torch::empty({latent, 0}), mlp.first()->bias, a, b, index));
      update = at::layer_norm(hidden, {latent});
      summed = segment_sum(update, index);
    }
    node_in.push_back(summed);
    latents[s] = latents[s] + update;
  }
  auto update = mode == EdgeMlpMode::kConcat ? node_mlp_->forward_reference(torch::cat(node_in, 1))
                                             : node_mlp_->forward_parts(node_in);
  return v + update;
}

MeshGraphNets::MeshGraphNets(GraphModelOptions options) : GraphModel(std::move(options)) {
  const int64_t latent = options_.latent;
  node_encoder_ = register_module("node_encoder",
                                  std::make_shared<Mlp>(options_.input_size, latent, latent, true));
  for (size_t s = 0; s < num_edge_sets(); ++s) {
    edge_encoders_.push_back(
        register_module("edge_encoder_" + std::to_string(s),
                        std::make_shared<Mlp>(edge_feature_size(s), latent, latent, true)));
  }
  for (int k = 0; k < options_.message_passing_steps; ++k) {
    blocks_.push_back(register_module("block_" + std::to_string(k),
                                      std::make_shared<EdgeLatentBlock>(latent, num_edge_sets())));
  }
  decoder_ = register_module("decoder",
                             std::make_shared<Mlp>(latent, latent, options_.output_size, false));
  make_edge_normalizers(1);
}

void MeshGraphNets::edge_inputs(const std::vector<torch::Tensor>& positions,
                                const MultilevelTensors& graph,
                                std::vector<std::vector<EdgeIndex>>* idx,
                                std::vector<std::vector<torch::Tensor>>* feats) const {
  idx->assign(1, {});
  feats->assign(1, {});
  for (size_t s = 0; s < num_edge_sets(); ++s) {
    (*idx)[0].push_back(edge_set(graph, 0, s));
    (*feats)[0].push_back(
        edge_features(positions, options_.edge_set_fields[s], (*idx)[0].back(), stretch(s)));
  }
}

torch::Tensor MeshGraphNets::forward(const torch::Tensor& nodes,
                                     const std::vector<torch::Tensor>& positions,
                                     const MultilevelTensors& graph) {
  check_inputs(nodes, positions, graph);
  std::vector<std::vector<EdgeIndex>> idx;
  std::vector<std::vector<torch::Tensor>> feats;
  edge_inputs(positions, graph, &idx, &feats);
  std::vector<const EdgeIndex*> edges;
  std::vector<torch::Tensor> latents;
  for (const auto& set : idx[0]) edges.push_back(&set);
  for (size_t s = 0; s < num_edge_sets(); ++s)
    latents.push_back(run_mlp(*edge_encoders_[s], normalize_edges(0, s, feats[0][s])));
  auto v = run_mlp(*node_encoder_, nodes);
  for (auto& block : blocks_) v = block->forward(v, latents, edges, mode_);
  return run_mlp(*decoder_, v);
}

}  // namespace bsms
