#include "models/layers.hpp"

#include <torch/nn/functional/normalization.h>

#include <string>

#include "core/error.hpp"
#include "models/graph_ops.hpp"

namespace bsms {
namespace {

torch::Tensor normalize_rows(const torch::Tensor& x) {
  return at::layer_norm(x, {x.size(-1)});
}

}  // namespace

Mlp::Mlp(int64_t in_size, int64_t hidden, int64_t out_size, bool layer_norm)
    : layer_norm_(layer_norm) {
  first_ = register_module("first", torch::nn::Linear(in_size, hidden));
  second_ = register_module("second", torch::nn::Linear(hidden, hidden));
  third_ = register_module("third", torch::nn::Linear(hidden, out_size));
}

torch::Tensor Mlp::second_layer(const torch::Tensor& hidden) {
  return linear(hidden, second_->weight, second_->bias, true);
}

torch::Tensor Mlp::tail(const torch::Tensor& hidden) {
  return linear(second_layer(hidden), third_->weight, third_->bias, false);
}

torch::Tensor Mlp::forward(const torch::Tensor& x) {
  auto y = tail(linear(x, first_->weight, first_->bias, true));
  return layer_norm_ ? normalize_rows(y) : y;
}

torch::Tensor Mlp::forward_reference(const torch::Tensor& x) {
  auto y = third_(torch::relu(second_(torch::relu(first_(x)))));
  return layer_norm_ ? normalize_rows(y) : y;
}

torch::Tensor edge_features(const std::vector<torch::Tensor>& positions,
                            const std::vector<int64_t>& fields, const EdgeIndex& edges,
                            const EdgeStretch& stretch) {
  auto check = [&](int64_t f) {
    if (f < 0 || f >= static_cast<int64_t>(positions.size())) {
      throw InputError("edge features: position field " + std::to_string(f) + " requested, " +
                       std::to_string(positions.size()) + " given");
    }
  };
  auto length = [&](int64_t f) {
    const auto& p = positions[f];
    return (p.index_select(0, edges.senders) - p.index_select(0, edges.receivers))
        .norm(2, {1}, /*keepdim=*/true);
  };
  std::vector<torch::Tensor> parts;
  for (int64_t f : fields) {
    check(f);
    const auto& p = positions[f];
    auto d = p.index_select(0, edges.senders) - p.index_select(0, edges.receivers);
    parts.push_back(d);
    parts.push_back(d.norm(2, {1}, /*keepdim=*/true));
  }
  if (stretch.enabled()) {
    check(stretch.reference);
    check(stretch.current);
    // Coincident reference nodes (a degenerate edge) read as unstretched.
    const auto rest = length(stretch.reference);
    const auto strain = torch::where(rest > 0, length(stretch.current) / rest.clamp_min(1e-30) - 1,
                                     torch::zeros_like(rest));
    parts.push_back(strain * stretch.inv_scale);
  }
  return torch::cat(parts, 1);
}

MessagePassing::MessagePassing(int64_t latent, const std::vector<int64_t>& edge_feature_sizes) {
  for (size_t s = 0; s < edge_feature_sizes.size(); ++s) {
    edge_mlps_.push_back(register_module(
        "edge_mlp_" + std::to_string(s),
        std::make_shared<Mlp>(edge_feature_sizes[s] + 2 * latent, latent, latent, true)));
  }
  node_mlp_ = register_module(
      "node_mlp",
      std::make_shared<Mlp>((1 + static_cast<int64_t>(edge_feature_sizes.size())) * latent, latent,
                            latent, true));
}

torch::Tensor MessagePassing::forward(const torch::Tensor& v,
                                      const std::vector<torch::Tensor>& features,
                                      const std::vector<EdgeIndex>& edges, EdgeMlpMode mode) {
  const size_t num_sets = edge_mlps_.size();
  if (features.size() != num_sets || edges.size() < num_sets) {
    throw InputError("message passing: expected " + std::to_string(num_sets) + " edge sets, got " +
                     std::to_string(features.size()) + " feature tensors and " +
                     std::to_string(edges.size()) + " edge indices");
  }
  const int64_t latent = v.size(1);
  std::vector<torch::Tensor> node_in{v};
  for (size_t s = 0; s < num_sets; ++s) {
    Mlp& mlp = *edge_mlps_[s];
    const EdgeIndex& index = edges[s];
    if (mode == EdgeMlpMode::kConcat) {
      auto x = torch::cat(
          {features[s], v.index_select(0, index.senders), v.index_select(0, index.receivers)}, 1);
      auto messages = mlp.forward_reference(x);
      node_in.push_back(torch::zeros_like(v).index_add_(0, index.receivers, messages));
      continue;
    }
    const auto& w = mlp.first()->weight;  // [L, F + 2L]: feature, sender, receiver columns
    const int64_t f = features[s].size(1);
    auto a = linear(v, w.narrow(1, f, latent), {}, false);
    auto b = linear(v, w.narrow(1, f + latent, latent), {}, false);
    if (!torch::GradMode::is_enabled()) {
      // Inference: the edge MLP and its sum in cache-sized tiles of edges (same math).
      node_in.push_back(edge_mlp_segment_sum(features[s], w.narrow(1, 0, f), mlp.first()->bias, a,
                                             b, mlp.second()->weight, mlp.second()->bias,
                                             mlp.third()->weight, mlp.third()->bias, index));
      continue;
    }
    auto hidden = edge_first_layer(torch::Tensor(), features[s], w.narrow(1, 0, f),
                                   mlp.first()->bias, a, b, index);
    auto y = linear(mlp.second_layer(hidden), mlp.third()->weight, {}, false);
    node_in.push_back(layer_norm_segment_sum(y, mlp.third()->bias, index));
  }
  auto update = mode == EdgeMlpMode::kConcat ? node_mlp_->forward_reference(torch::cat(node_in, 1))
                                             : node_mlp_->forward(torch::cat(node_in, 1));
  return v + update;
}

Normalizer::Normalizer(int64_t size, int64_t max_accumulations, double std_epsilon) : size_(size) {
  auto f64 = torch::TensorOptions().dtype(torch::kFloat64);
  count_ = register_buffer("count", torch::zeros({1}, f64));
  num_accumulations_ = register_buffer("num_accumulations", torch::zeros({1}, f64));
  max_accumulations_ =
      register_buffer("max_accumulations", torch::full({1}, double(max_accumulations), f64));
  std_epsilon_ = register_buffer("std_epsilon", torch::full({1}, std_epsilon, f64));
  sum_ = register_buffer("sum", torch::zeros({size}, f64));
  sum_squares_ = register_buffer("sum_squares", torch::zeros({size}, f64));
}

void Normalizer::accumulate(const torch::Tensor& x) {
  if (x.size(-1) != size_) {
    throw InputError("normalizer: features have " + std::to_string(x.size(-1)) +
                     " channels, expected " + std::to_string(size_));
  }
  if (num_accumulations_.item<double>() >= max_accumulations_.item<double>()) return;
  torch::NoGradGuard no_grad;
  auto rows = x.reshape({-1, size_}).to(torch::kFloat64);
  count_.add_(rows.size(0));
  num_accumulations_.add_(1);
  sum_.add_(rows.sum(0));
  sum_squares_.add_(rows.square().sum(0));
}

torch::Tensor Normalizer::mean() const {
  return sum_ / count_.clamp_min(1.0);
}

torch::Tensor Normalizer::std() const {
  auto m = mean();
  auto var = (sum_squares_ / count_.clamp_min(1.0) - m * m).clamp_min(0.0);
  return torch::max(var.sqrt(), std_epsilon_);
}

torch::Tensor Normalizer::normalize(const torch::Tensor& x) const {
  return (x - mean().to(torch::kFloat32)) / std().to(torch::kFloat32);
}

torch::Tensor Normalizer::inverse(const torch::Tensor& x) const {
  return x * std().to(torch::kFloat32) + mean().to(torch::kFloat32);
}

}  // namespace bsms
