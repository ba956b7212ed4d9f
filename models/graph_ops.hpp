// Fused linear, gather and segment-sum kernels with autograd, on contiguous float32 tensors. Sums
// over the edges of a node run as segment reductions in EdgeIndex order: deterministic, no atomics,
// parallel over nodes with the LibTorch thread pool.
#pragma once

#include <torch/types.h>

#include <string>

#include "models/graph_tensors.hpp"

namespace bsms {

// The first layer of an edge MLP as a sum of per-node projections, with its ReLU:
//   relu(base[e] + features[e] · weightᵀ + bias + a[senders[e]] + b[receivers[e]]).
// base [E, C] or undefined; features [E, K] (K may be 0) with weight [C, K]; bias [C];
// a and b [N, C] -> [E, C].
torch::Tensor edge_first_layer(const torch::Tensor& base, const torch::Tensor& features,
                               const torch::Tensor& weight, const torch::Tensor& bias,
                               const torch::Tensor& a, const torch::Tensor& b,
                               const EdgeIndex& edges);

// x · weightᵀ + bias, optionally followed by ReLU. The GEMMs are split over the LibTorch threads
// (row blocks; output blocks for the weight gradient), each block one oneDNN sgemm on its worker
// thread, and bias and ReLU are applied to each block while it is in cache.
// x [R, in], weight [out, in], bias [out] or undefined -> [R, out].
torch::Tensor linear(const torch::Tensor& x, const torch::Tensor& weight, const torch::Tensor& bias,
                     bool relu);

// LibTorch's half of core/runtime.hpp's set_num_threads: sets LibTorch's thread count (<= 0: keep
// it) and makes OpenBLAS single-threaded (core's single_threaded_blas): the kernels split their
// products over LibTorch's OpenMP pool themselves, and a product that falls back to LibTorch's
// BLAS inside a worker must not start threads of its own. Returns the LibTorch thread count.
int configure_threads(int threads);

// Precision of the kernels' matrix products. kBFloat16: both operands rounded to bfloat16 and
// multiplied by oneDNN (LibTorch's mkldnn), whose bfloat16 GEMM runs at twice float32's rate on
// CPUs with AVX-512 BF16 (Zen 4, Cooper Lake and later Xeons); products accumulate in float32
// but come back rounded to bfloat16 before they are widened again. Everything else (bias, ReLU,
// LayerNorm, sums over edges, parameters, optimizer state) stays float32. Process-wide; set by
// training and rollout from the model config (model.precision).
enum class MatmulPrecision { kFloat32, kBFloat16 };
void set_matmul_precision(MatmulPrecision precision);
MatmulPrecision matmul_precision();
// The library and the instruction set of the float32 products, e.g. "oneDNN 2.6.3 sgemm,
// avx512_core_bf16" (oneDNN's effective ISA on this CPU).
std::string matmul_library();

// One layer of mlp_inference: x · weightᵀ + bias (bias may be undefined), then ReLU if `relu`.
struct DenseLayer {
  torch::Tensor weight, bias;
  bool relu = false;
};

// Inference (no gradients): dense layers in sequence, optionally a LayerNorm (no affine, eps
// 1e-5) on the last output, like linear() layer by layer but with each worker taking its block of
// rows through every layer. The input is the column concatenation of `parts` (all with the same
// rows), never built: the first layer sums each part's GEMM with its columns of the weight.
// part_rows (empty: all parts dense) marks sparse parts: part_rows[p] int64 [R] lists the distinct
// ascending rows that parts[p] [R, k] gives; its other rows are zero (e.g. the sum of contact
// messages, which reaches few nodes). The first part is dense.
torch::Tensor mlp_inference(const std::vector<torch::Tensor>& parts,
                            const std::vector<DenseLayer>& layers, bool layer_norm,
                            const std::vector<torch::Tensor>& part_rows = {});

// out[j] = Σ_{e: receivers[e] = j} layer_norm(x[e] + bias) (no affine, eps 1e-5), without storing
// the normalised edge tensor. x [E, C], bias [C] -> [N, C].
torch::Tensor layer_norm_segment_sum(const torch::Tensor& x, const torch::Tensor& bias,
                                     const EdgeIndex& edges);

// Inference only (no autograd; the inputs must not need gradients): a message-passing step's whole
// edge MLP and the sum over each receiver's edges, computed in tiles of edges that stay in cache
// instead of as four [E, C] tensors:
//   out[j] = Σ_{e: receivers[e] = j} layer_norm(relu(h1_e · w2ᵀ + b2) · w3ᵀ + b3),
//   h1_e = relu(features[e] · w1ᵀ + b1 + a[senders[e]] + b[receivers[e]]).
// The same math as edge_first_layer → linear(relu) → linear → layer_norm_segment_sum.
// With b undefined, a [E, C] holds each edge's endpoint term (a[senders[e]] + b[receivers[e]]
// above): for edge sets much smaller than the node count (contacts), projecting the endpoints of
// each edge costs less than projecting every node.
torch::Tensor edge_mlp_segment_sum(const torch::Tensor& features, const torch::Tensor& w1,
                                   const torch::Tensor& b1, const torch::Tensor& a,
                                   const torch::Tensor& b, const torch::Tensor& w2,
                                   const torch::Tensor& b2, const torch::Tensor& w3,
                                   const torch::Tensor& b3, const EdgeIndex& edges);

// Inference only: a MeshGraphNets edge-latent update (models/networks.cpp EdgeLatentBlock) in
// tiles of edges that stay in cache:
//   y_e = layer_norm(relu(relu(latent[e] · w1ᵀ + b1 + a[senders[e]] + b[receivers[e]]) · w2ᵀ + b2)
//                    · w3ᵀ + b3),
// writes latent_out[e] = latent[e] + y_e (a new [E, C] tensor) and returns
// out[j] = Σ_{e: receivers[e] = j} y_e. Of the edge MLP's tensors only the LayerNorm output is
// written. The same math as edge_first_layer → tail → layer_norm → segment_sum.
torch::Tensor edge_latent_update(const torch::Tensor& latent, const torch::Tensor& w1,
                                 const torch::Tensor& b1, const torch::Tensor& a,
                                 const torch::Tensor& b, const torch::Tensor& w2,
                                 const torch::Tensor& b2, const torch::Tensor& w3,
                                 const torch::Tensor& b3, const EdgeIndex& edges,
                                 torch::Tensor& latent_out);

// out[j] = Σ_{e: receivers[e] = j} x[e]. x [E, C] -> [N, C].
torch::Tensor segment_sum(const torch::Tensor& x, const EdgeIndex& edges);

// Down transition: D v, v [N_fine, C] -> [N_coarse, C] (models/graph_tensors.hpp).
torch::Tensor transition_down(const torch::Tensor& v, const LevelTransition& transition);
// Up transition: Dᵀ v, v [N_coarse, C] -> [N_fine, C].
torch::Tensor transition_up(const torch::Tensor& v, const LevelTransition& transition);

}  // namespace bsms
