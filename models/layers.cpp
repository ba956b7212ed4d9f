#include "models/layers.hpp"

#include <ATen/Dispatch.h>
#include <ATen/Parallel.h>
#include <torch/nn/functional/normalization.h>

#include <algorithm>
#include <cmath>

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
  if (!torch::GradMode::is_enabled()) return forward_parts({x});
  auto y = tail(linear(x, first_->weight, first_->bias, true));
  return layer_norm_ ? normalize_rows(y) : y;
}

torch::Tensor Mlp::forward_parts(const std::vector<torch::Tensor>& parts,
                                 const std::vector<torch::Tensor>& part_rows) {
  if (!torch::GradMode::is_enabled()) {
    return mlp_inference(parts,
                         {{first_->weight, first_->bias, true},
                          {second_->weight, second_->bias, true},
                          {third_->weight, third_->bias, false}},
                         layer_norm_, part_rows);
  }
  if (!part_rows.empty())
    throw InputError("MLP: sparse input parts are for inference (no gradients)");
  return forward(parts.size() == 1 ? parts[0] : torch::cat(parts, 1));
}

torch::Tensor Mlp::forward_reference(const torch::Tensor& x) {
  auto y = third_(torch::relu(second_(torch::relu(first_(x)))));
  return layer_norm_ ? normalize_rows(y) : y;
}

namespace {

// Rows [e0, e1) of edge_features in one pass over the edges: the values of the tensor formula
// (index_select, difference, norm and concatenation per field) without its ~10 small ops per field
// and level, which were much of a small graph's per-step overhead.
template <class T>
void edge_feature_rows(const std::vector<const T*>& p, const std::vector<int64_t>& dims,
                       const std::vector<int64_t>& fields, const EdgeStretch& stretch,
                       const int64_t* senders, const int64_t* receivers, int64_t e0, int64_t e1,
                       int64_t width, T* out) {
  auto delta_length = [&](int64_t f, int64_t s, int64_t r, T* d) {
    const int64_t dim = dims[f];
    const T* ps = p[f] + s * dim;
    const T* pr = p[f] + r * dim;
    T sq = 0;
    for (int64_t c = 0; c < dim; ++c) {
      const T v = ps[c] - pr[c];
      if (d) d[c] = v;
      sq += v * v;
    }
    return std::sqrt(sq);
  };
  for (int64_t e = e0; e < e1; ++e) {
    const int64_t s = senders[e], r = receivers[e];
    T* o = out + e * width;
    for (int64_t f : fields) {
      o[dims[f]] = delta_length(f, s, r, o);
      o += dims[f] + 1;
    }
    if (stretch.enabled()) {
      // Coincident reference nodes (a degenerate edge) read as unstretched.
      const T rest = delta_length(stretch.reference, s, r, nullptr);
      const T now = delta_length(stretch.current, s, r, nullptr);
      *o = rest > 0 ? (now / std::max(rest, T(1e-30)) - 1) * static_cast<T>(stretch.inv_scale)
                    : T(0);
    }
  }
}

}  // namespace

torch::Tensor edge_features(const std::vector<torch::Tensor>& positions,
                            const std::vector<int64_t>& fields, const EdgeIndex& edges,
                            const EdgeStretch& stretch) {
  auto check = [&](int64_t f) {
    if (f < 0 || f >= static_cast<int64_t>(positions.size())) {
      throw InputError("edge features: position field " + std::to_string(f) + " requested, " +
                       std::to_string(positions.size()) + " given");
    }
  };
  for (int64_t f : fields) check(f);
  if (stretch.enabled()) {
    check(stretch.reference);
    check(stretch.current);
  }
  if (positions.empty()) throw InputError("edge features: no position fields given");
  const auto dtype = positions[0].scalar_type();
  if (dtype != torch::kFloat32 && dtype != torch::kFloat64)
    throw InputError("edge features: positions must be float32 or float64");
  std::vector<torch::Tensor> p;
  std::vector<int64_t> dims;
  for (const auto& t : positions) {
    if (t.dim() != 2 || t.scalar_type() != dtype)
      throw InputError("edge features: every position field must be 2-D and of one dtype, got " +
                       std::string(c10::str(t.sizes())) + " " +
                       std::string(c10::toString(t.scalar_type())));
    if (edges.num_nodes > t.size(0))
      throw InputError("edge features: edges index " + std::to_string(edges.num_nodes) +
                       " nodes, a position field has " + std::to_string(t.size(0)));
    p.push_back(t.detach().contiguous());
    dims.push_back(t.size(1));
  }
  int64_t width = stretch.enabled() ? 1 : 0;
  for (int64_t f : fields) width += dims[f] + 1;
  if (stretch.enabled() && dims[stretch.reference] != dims[stretch.current])
    throw InputError("edge features: the stretch channel's position fields differ in size");
  const int64_t count = edges.num_edges();
  auto out = torch::empty({count, width}, positions[0].options().requires_grad(false));
  if (count == 0) return out;
  const auto senders = edges.senders.contiguous(), receivers = edges.receivers.contiguous();
  const int64_t* ps = senders.data_ptr<int64_t>();
  const int64_t* pr = receivers.data_ptr<int64_t>();
  AT_DISPATCH_FLOATING_TYPES(dtype, "edge_features", [&] {
    std::vector<const scalar_t*> raw;
    for (const auto& t : p) raw.push_back(t.data_ptr<scalar_t>());
    scalar_t* po = out.data_ptr<scalar_t>();
    at::parallel_for(0, count, 4096, [&](int64_t e0, int64_t e1) {
      edge_feature_rows<scalar_t>(raw, dims, fields, stretch, ps, pr, e0, e1, width, po);
    });
  });
  return out;
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
  std::vector<torch::Tensor> node_rows(1 + num_sets);  // inference: rows of a sparse sum
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
    if (!torch::GradMode::is_enabled() && 2 * index.num_edges() < v.size(0)) {
      // Inference on few edges (contacts): the endpoint term per edge, not per node.
      const auto ends =
          mlp_inference({v.index_select(0, index.senders), v.index_select(0, index.receivers)},
                        {{w.narrow(1, f, 2 * latent), {}, false}}, false);
      const auto sum = edge_mlp_segment_sum(features[s], w.narrow(1, 0, f), mlp.first()->bias, ends,
                                            {}, mlp.second()->weight, mlp.second()->bias,
                                            mlp.third()->weight, mlp.third()->bias, index);
      // Only the receivers' rows are not zero: the node MLP takes just those.
      const auto& offsets = index.receiver_offsets;
      const auto receiving = (offsets.slice(0, 1) > offsets.slice(0, 0, -1)).nonzero().squeeze(1);
      node_rows[1 + s] = receiving;
      node_in.push_back(sum.index_select(0, receiving));
      continue;
    }
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
  if (!torch::GradMode::is_enabled() && mode != EdgeMlpMode::kConcat)
    return v + node_mlp_->forward_parts(node_in, node_rows);
  auto update = mode == EdgeMlpMode::kConcat ? node_mlp_->forward_reference(torch::cat(node_in, 1))
                                             : node_mlp_->forward_parts(node_in);
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

bool Normalizer::empty() const {
  return count_.item<double>() == 0.0;
}

torch::Tensor Normalizer::mean() const {
  return sum_ / count_.clamp_min(1.0);
}

torch::Tensor Normalizer::std() const {
  auto m = mean();
  auto var = (sum_squares_ / count_.clamp_min(1.0) - m * m).clamp_min(0.0);
  return torch::max(var.sqrt(), std_epsilon_);
}

const Normalizer::FloatStats& Normalizer::float_stats() const {
  FloatStats& c = cached_;
  const uint32_t count = count_._version(), sum = sum_._version(),
                 squares = sum_squares_._version();
  if (!c.mean.defined() || c.count_version != count || c.sum_version != sum ||
      c.squares_version != squares) {
    c.mean = mean().to(torch::kFloat32);
    c.std = std().to(torch::kFloat32);
    c.count_version = count;
    c.sum_version = sum;
    c.squares_version = squares;
  }
  return c;
}

torch::Tensor Normalizer::normalize(const torch::Tensor& x) const {
  if (!torch::GradMode::is_enabled()) {
    const FloatStats& c = float_stats();
    return (x - c.mean) / c.std;
  }
  return (x - mean().to(torch::kFloat32)) / std().to(torch::kFloat32);
}

torch::Tensor Normalizer::inverse(const torch::Tensor& x) const {
  if (!torch::GradMode::is_enabled()) {
    const FloatStats& c = float_stats();
    return x * c.std + c.mean;
  }
  return x * std().to(torch::kFloat32) + mean().to(torch::kFloat32);
}

}  // namespace bsms
