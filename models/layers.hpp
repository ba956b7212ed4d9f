// Building blocks shared by BSMS-GNN and MeshGraphNets (thesis §4.3.1, §4.4.2.1): MLP, edge
// features, the BSMS message-passing block and the running-statistics normalizer.
#pragma once

#include <torch/nn/module.h>
#include <torch/nn/modules/linear.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "models/graph_tensors.hpp"

namespace bsms {

// Linear -> ReLU -> Linear -> ReLU -> Linear, hidden width `hidden`, optional LayerNorm (no affine
// parameters, eps 1e-5) on the output.
class Mlp : public torch::nn::Module {
 public:
  Mlp(int64_t in_size, int64_t hidden, int64_t out_size, bool layer_norm);
  // [R, in] -> [R, out], bias and ReLU fused (models/graph_ops.hpp).
  torch::Tensor forward(const torch::Tensor& x);
  // forward on the column concatenation of `parts`; without gradients it is never built and each
  // worker takes its rows through all three layers (models/graph_ops.hpp, mlp_inference, which
  // also says what `part_rows` marks; inference only).
  torch::Tensor forward_parts(const std::vector<torch::Tensor>& parts,
                              const std::vector<torch::Tensor>& part_rows = {});
  // The same with plain LibTorch modules and ops, as the reference implementation evaluates it.
  torch::Tensor forward_reference(const torch::Tensor& x);
  // Layer 2 with its ReLU, from the first layer's ReLU output: [R, hidden] -> [R, hidden].
  torch::Tensor second_layer(const torch::Tensor& hidden);
  // Layers 2 and 3 (no LayerNorm): [R, hidden] -> [R, out].
  torch::Tensor tail(const torch::Tensor& hidden);

  const torch::nn::Linear& first() const { return first_; }
  const torch::nn::Linear& second() const { return second_; }
  const torch::nn::Linear& third() const { return third_; }
  bool layer_norm() const { return layer_norm_; }
  int64_t in_size() const { return first_->options.in_features(); }

 private:
  torch::nn::Linear first_{nullptr}, second_{nullptr}, third_{nullptr};
  bool layer_norm_;
};

// The stretch of an edge between a reference and a current position field: the rotation-
// invariant strain (|Δp_current| / |Δp_reference| - 1) times `inv_scale` (typically 1 / the RMS
// strain of the training data, so that deformation reaches the first layer at O(1) instead of as a
// small difference of two O(1) lengths). reference < 0: no stretch channel.
struct EdgeStretch {
  int64_t reference = -1;
  int64_t current = -1;
  double inv_scale = 1.0;
  bool enabled() const { return reference >= 0; }
};

// Edge features [Δp, |Δp|] for each position field in `fields` (Δp = p[sender] - p[receiver]),
// concatenated, then the stretch channel when `stretch` is enabled:
// positions[f] [N, d_f] -> [E, Σ_f (d_f + 1) (+ 1)], float32 or float64 like the positions; one
// pass over the edges, no gradient taken through the positions.
torch::Tensor edge_features(const std::vector<torch::Tensor>& positions,
                            const std::vector<int64_t>& fields, const EdgeIndex& edges,
                            const EdgeStretch& stretch = {});

// How the first edge-MLP layer is evaluated. kProjection: W·[f, v_i, v_j] = W_f f + (W_i v)[i] +
// (W_j v)[j] with node-sized matmuls and fused gather/segment-sum kernels. kConcat: the plain
// concat-then-Linear formulation of the reference implementation (same parameters, same math).
enum class EdgeMlpMode { kProjection, kConcat };

// One BSMS message-passing pass (thesis eq. 4.2) over S edge sets: per set s,
// e = f_s([features, v_sender, v_receiver]); v' = v + f_V([v, Σ_j e¹, …, Σ_j eˢ]).
class MessagePassing : public torch::nn::Module {
 public:
  MessagePassing(int64_t latent, const std::vector<int64_t>& edge_feature_sizes);
  // v [N, L]; features[s] [E_s, F_s]; edges.size() >= S (extra sets are ignored). -> [N, L]
  torch::Tensor forward(const torch::Tensor& v, const std::vector<torch::Tensor>& features,
                        const std::vector<EdgeIndex>& edges, EdgeMlpMode mode);

 private:
  std::vector<std::shared_ptr<Mlp>> edge_mlps_;
  std::shared_ptr<Mlp> node_mlp_;
};

// Running mean and standard deviation of features, accumulated over calls (max_accumulations
// calls at most) and saved with the model as float64 buffers.
class Normalizer : public torch::nn::Module {
 public:
  explicit Normalizer(int64_t size, int64_t max_accumulations = 1000000, double std_epsilon = 1e-8);
  // Adds the rows of x [R, C] to the statistics (no-op once max_accumulations is reached).
  void accumulate(const torch::Tensor& x);
  torch::Tensor normalize(const torch::Tensor& x) const;  // [R, C] -> [R, C] float32
  torch::Tensor inverse(const torch::Tensor& x) const;    // [R, C] -> [R, C] float32
  torch::Tensor mean() const;                             // [C] float64
  torch::Tensor std() const;                              // [C] float64, >= std_epsilon
  int64_t size() const { return size_; }
  bool empty() const;  // no row accumulated yet
  // The sums the statistics are made of (rows, sum, sum of squares): data-parallel training adds
  // them up over the ranks after accumulating.
  std::vector<torch::Tensor> sums() { return {count_, sum_, sum_squares_}; }

 private:
  int64_t size_;
  torch::Tensor count_;              // [1] float64: rows accumulated
  torch::Tensor num_accumulations_;  // [1] float64: calls accumulated
  torch::Tensor max_accumulations_;  // [1] float64
  torch::Tensor std_epsilon_;        // [1] float64
  torch::Tensor sum_;                // [C] float64
  torch::Tensor sum_squares_;        // [C] float64
  // Without gradients (rollouts, validation): the float32 mean and std, kept until a statistic
  // buffer changes (accumulation, checkpoint load, allreduce bump their version counters).
  struct FloatStats {
    torch::Tensor mean, std;
    uint32_t count_version = 0, sum_version = 0, squares_version = 0;
  };
  mutable FloatStats cached_;
  const FloatStats& float_stats() const;
};

}  // namespace bsms
