#include "models/graph_ops.hpp"

#include <ATen/Parallel.h>
#include <ATen/ThreadLocalState.h>
#include <ATen/record_function.h>
#include <torch/autograd.h>

#include <oneapi/dnnl/dnnl.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/error.hpp"
#include "core/runtime.hpp"

namespace bsms {
namespace {

using torch::autograd::AutogradContext;
using torch::autograd::variable_list;

constexpr float kLayerNormEps = 1e-5f;

int64_t grain_rows(int64_t channels) {
  return std::max<int64_t>(1, 8192 / std::max<int64_t>(1, channels));
}

torch::Tensor checked_float(const torch::Tensor& t, const char* name) {
  if (t.scalar_type() != torch::kFloat32 || t.dim() != 2) {
    throw InputError(std::string("graph kernel: ") + name + " must be a 2-D float32 tensor, got " +
                     std::string(c10::toString(t.scalar_type())) + " " +
                     std::string(c10::str(t.sizes())));
  }
  return t.contiguous();
}

const int64_t* ptr(const torch::Tensor& t) {
  return t.data_ptr<int64_t>();
}

std::atomic<int> g_matmul_precision{static_cast<int>(MatmulPrecision::kFloat32)};

bool bf16_products() {
  return g_matmul_precision.load(std::memory_order_relaxed) ==
         static_cast<int>(MatmulPrecision::kBFloat16);
}

// A weight operand as the products take it: in bfloat16 mode rounded once per kernel call (not
// per tile), else the float32 tensor itself.
torch::Tensor gemm_operand(const torch::Tensor& w, bool bf16 = bf16_products()) {
  return bf16 ? w.to(torch::kBFloat16).contiguous() : w;
}

// Float32 products go to oneDNN's sgemm rather than LibTorch's BLAS (OpenBLAS on Debian).
// oneDNN chooses its kernels from the instruction sets the CPU reports. OpenBLAS 0.3.21 chooses
// them from a table of CPU models (SSE3 kernels for a model it does not know) and follows any
// OPENBLAS_CORETYPE left in the environment, so the same binary ran 1.6x slower in a shell that
// had OPENBLAS_CORETYPE=Haswell set. oneDNN's kernels also beat OpenBLAS's best on the 128-wide
// products of the edge MLPs (docs/results.md, "Speed on Zen 5"). Inside the kernels' parallel
// regions oneDNN runs on the calling thread.
struct SgemmOperand {
  char trans = 'N';
  int64_t ld = 0;
  bool ok = false;
};

// A 2-D float32 tensor as oneDNN's row-major operand: rows contiguous ('N'), or columns ('T', a
// transposed view).
SgemmOperand sgemm_operand(const torch::Tensor& t) {
  const int64_t rows = t.size(0), cols = t.size(1);
  if (t.stride(1) == 1 && t.stride(0) >= std::max<int64_t>(1, cols))
    return {'N', t.stride(0), true};
  if (t.stride(0) == 1 && t.stride(1) >= std::max<int64_t>(1, rows))
    return {'T', t.stride(1), true};
  return {};
}

// out = a · b + beta · out through oneDNN; false when a layout does not fit (the caller falls
// back to LibTorch).
bool sgemm(torch::Tensor& out, const torch::Tensor& a, const torch::Tensor& b, float beta) {
  const int64_t m = a.size(0), k = a.size(1), n = b.size(1);
  if (m == 0 || n == 0) return true;
  const SgemmOperand oa = sgemm_operand(a), ob = sgemm_operand(b);
  if (!oa.ok || !ob.ok || k == 0 || out.stride(1) != 1 || out.stride(0) < n) return false;
  const dnnl_status_t status =
      dnnl_sgemm(oa.trans, ob.trans, m, n, k, 1.0f, a.data_ptr<float>(), oa.ld, b.data_ptr<float>(),
                 ob.ld, beta, out.data_ptr<float>(), out.stride(0));
  if (status != dnnl_success) {
    throw std::runtime_error("oneDNN sgemm failed (status " + std::to_string(status) + ") on " +
                             std::to_string(m) + "x" + std::to_string(k) + " by " +
                             std::to_string(k) + "x" + std::to_string(n));
  }
  return true;
}

// out = a · b, out and a float32; b float32 or gemm_operand's bfloat16.
void gemm_out(torch::Tensor& out, const torch::Tensor& a, const torch::Tensor& b) {
  if (b.scalar_type() != torch::kBFloat16) {
    if (!sgemm(out, a, b, 0.0f)) at::mm_out(out, a, b);
    return;
  }
  out.copy_(at::mm(a.to(torch::kBFloat16), b));
}

// out += a · b, as gemm_out.
void gemm_add(torch::Tensor& out, const torch::Tensor& a, const torch::Tensor& b) {
  if (b.scalar_type() != torch::kBFloat16) {
    if (!sgemm(out, a, b, 1.0f)) out.addmm_(a, b);
    return;
  }
  out.add_(at::mm(a.to(torch::kBFloat16), b));
}

torch::Tensor gemm(const torch::Tensor& a, const torch::Tensor& b) {
  if (b.scalar_type() != torch::kBFloat16) {
    auto out = torch::empty({a.size(0), b.size(1)}, a.options());
    gemm_out(out, a, b);
    return out;
  }
  return at::mm(a.to(torch::kBFloat16), b).to(torch::kFloat32);
}

// Row kernels on raw float rows of `channels` values. Cloned for x86-64-v4 (AVX-512) and
// x86-64-v3 (AVX2, FMA) with a baseline fallback chosen at load time; `omp simd` lets the
// reductions vectorise.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#define BSMS_ROW_KERNEL \
  __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define BSMS_ROW_KERNEL
#endif

// max(x, 0) by value: std::max returns a reference to one of its arguments, which keeps GCC from
// vectorising the loops below (measured: scalar blends, ~6 % of a small-graph rollout each).
inline float relu_value(float x) {
  return x > 0.0f ? x : 0.0f;
}

// o = Σ_q w[q] · x[idx[q]] for q in [q0, q1); w may be null (weights 1).
BSMS_ROW_KERNEL void gather_sum_row(const float* x, const int64_t* idx, const float* w, int64_t q0,
                                    int64_t q1, int64_t channels, float* o) {
  for (int64_t c = 0; c < channels; ++c) o[c] = 0.0f;
  for (int64_t q = q0; q < q1; ++q) {
    const float* xs = x + idx[q] * channels;
    const float wq = w ? w[q] : 1.0f;
#pragma omp simd
    for (int64_t c = 0; c < channels; ++c) o[c] += wq * xs[c];
  }
}

// m = g where o > 0 else 0, for rows [r0, r1); sum += Σ_rows m.
BSMS_ROW_KERNEL void relu_mask_rows(const float* o, const float* g, int64_t r0, int64_t r1,
                                    int64_t channels, float* m, float* sum) {
  for (int64_t i = r0 * channels; i < r1 * channels; i += channels) {
#pragma omp simd
    for (int64_t c = 0; c < channels; ++c) {
      const float v = o[i + c] > 0.0f ? g[i + c] : 0.0f;
      m[i + c] = v;
      sum[c] += v;
    }
  }
}

// sum += Σ_rows g for rows [r0, r1).
BSMS_ROW_KERNEL void column_sum_rows(const float* g, int64_t r0, int64_t r1, int64_t channels,
                                     float* sum) {
  for (int64_t i = r0 * channels; i < r1 * channels; i += channels) {
#pragma omp simd
    for (int64_t c = 0; c < channels; ++c) sum[c] += g[i + c];
  }
}

// Rows [r0, r1) of y: y = relu?(y + bias?).
BSMS_ROW_KERNEL void bias_relu_rows(float* y, const float* bias, bool relu, int64_t r0, int64_t r1,
                                    int64_t channels) {
  for (int64_t i = r0 * channels; i < r1 * channels; i += channels) {
    if (bias) {
#pragma omp simd
      for (int64_t c = 0; c < channels; ++c) y[i + c] += bias[c];
    }
    if (relu) {
#pragma omp simd
      for (int64_t c = 0; c < channels; ++c) y[i + c] = relu_value(y[i + c]);
    }
  }
}

// o = relu(base? + bias + a + b + Σ_q f[q] · wt[q]) for one edge; wt [K, C].
BSMS_ROW_KERNEL void edge_first_row(const float* base, const float* bias, const float* a,
                                    const float* b, const float* f, const float* wt, int64_t k,
                                    int64_t channels, float* o) {
#pragma omp simd
  for (int64_t c = 0; c < channels; ++c) o[c] = (base ? base[c] : 0.0f) + bias[c] + a[c] + b[c];
  for (int64_t q = 0; q < k; ++q) {
    const float fq = f[q];
    const float* w = wt + q * channels;
#pragma omp simd
    for (int64_t c = 0; c < channels; ++c) o[c] += fq * w[c];
  }
#pragma omp simd
  for (int64_t c = 0; c < channels; ++c) o[c] = relu_value(o[c]);
}

struct LayerNormStats {
  float mean, rstd;  // of the row, and 1/std (biased variance + eps)
};

// The LayerNorm statistics of the row x + bias (no affine, like at::layer_norm), defined once for
// every kernel that normalises rows. Always inlined: each caller vectorises it for its own
// instruction set (a row kernel's clone, or the default target), so the figures stay those of
// the loops written in place.
[[gnu::always_inline]] inline LayerNormStats layer_norm_stats(const float* x, const float* bias,
                                                              int64_t channels, float eps) {
  float sum = 0.0f;
#pragma omp simd reduction(+ : sum)
  for (int64_t c = 0; c < channels; ++c) sum += x[c] + bias[c];
  const float mean = sum / static_cast<float>(channels);
  float var = 0.0f;
#pragma omp simd reduction(+ : var)
  for (int64_t c = 0; c < channels; ++c) {
    const float d = x[c] + bias[c] - mean;
    var += d * d;
  }
  return {mean, 1.0f / std::sqrt(var / static_cast<float>(channels) + eps)};
}

// Layer norm of x + bias (no affine): returns (mean, 1/std) and adds the normalised row to o.
BSMS_ROW_KERNEL void layer_norm_accumulate_row(const float* x, const float* bias, int64_t channels,
                                               float eps, float* stats, float* o) {
  const LayerNormStats s = layer_norm_stats(x, bias, channels, eps);
  stats[0] = s.mean;
  stats[1] = s.rstd;
#pragma omp simd
  for (int64_t c = 0; c < channels; ++c) o[c] += (x[c] + bias[c] - s.mean) * s.rstd;
}

// y = layer_norm(y + bias) in place for rows [r0, r1) (no affine, like at::layer_norm).
BSMS_ROW_KERNEL void bias_layer_norm_rows(float* y, const float* bias, int64_t r0, int64_t r1,
                                          int64_t channels, float eps) {
  for (int64_t i = r0 * channels; i < r1 * channels; i += channels) {
    float* row = y + i;
    const LayerNormStats s = layer_norm_stats(row, bias, channels, eps);
#pragma omp simd
    for (int64_t c = 0; c < channels; ++c) row[c] = (row[c] + bias[c] - s.mean) * s.rstd;
  }
}

// acc[q, :] += f[q] · g for q in [0, k): one edge's outer product, acc [K, C] (C contiguous).
BSMS_ROW_KERNEL void outer_accumulate_row(const float* g, const float* f, int64_t k,
                                          int64_t channels, float* acc) {
  for (int64_t q = 0; q < k; ++q) {
    const float fq = f[q];
    float* a = acc + q * channels;
#pragma omp simd
    for (int64_t c = 0; c < channels; ++c) a[c] += fq * g[c];
  }
}

// Layer-norm backward for one row: d = rstd (g - mean(g) - x̂ mean(g x̂)); sum_d += d.
BSMS_ROW_KERNEL void layer_norm_backward_row(const float* x, const float* bias, const float* g,
                                             const float* stats, int64_t channels, float* d,
                                             float* sum_d) {
  const float mean = stats[0], rstd = stats[1];
  float sum_g = 0.0f, sum_gx = 0.0f;
#pragma omp simd reduction(+ : sum_g, sum_gx)
  for (int64_t c = 0; c < channels; ++c) {
    sum_g += g[c];
    sum_gx += g[c] * (x[c] + bias[c] - mean);
  }
  const float inv_c = 1.0f / static_cast<float>(channels);
  const float mg = sum_g * inv_c;
  const float mgx = sum_gx * inv_c * rstd;
#pragma omp simd
  for (int64_t c = 0; c < channels; ++c) {
    d[c] = rstd * (g[c] - mg - (x[c] + bias[c] - mean) * rstd * mgx);
    sum_d[c] += d[c];
  }
}

// out[n, :] = Σ_{q ∈ [off[n], off[n+1])} w[q] · x[idx[q], :]; w may be null (weights 1).
void segment_gather_sum(const float* x, int64_t channels, const int64_t* off, const int64_t* idx,
                        const float* w, int64_t rows, float* out) {
  at::parallel_for(0, rows, grain_rows(channels), [&](int64_t begin, int64_t end) {
    for (int64_t n = begin; n < end; ++n) {
      gather_sum_row(x, idx, w, off[n], off[n + 1], channels, out + n * channels);
    }
  });
}

torch::Tensor segment_sum_tensor(const torch::Tensor& x, const torch::Tensor& offsets,
                                 const torch::Tensor& order, int64_t rows) {
  auto xc = x.contiguous();
  auto out = torch::empty({rows, xc.size(1)}, xc.options());
  segment_gather_sum(xc.data_ptr<float>(), xc.size(1), ptr(offsets), ptr(order), nullptr, rows,
                     out.data_ptr<float>());
  return out;
}

torch::Tensor sparse_rows(const torch::Tensor& x, const torch::Tensor& offsets,
                          const torch::Tensor& columns, const torch::Tensor& values, int64_t rows) {
  auto xc = x.contiguous();
  auto out = torch::empty({rows, xc.size(1)}, xc.options());
  segment_gather_sum(xc.data_ptr<float>(), xc.size(1), ptr(offsets), ptr(columns),
                     values.data_ptr<float>(), rows, out.data_ptr<float>());
  return out;
}

// CSR arrays of Aᵀ [cols, rows] from those of A [rows, cols], by a stable counting sort on the
// column, so entries of each row of Aᵀ keep the row order of A.
struct CsrArrays {
  torch::Tensor offsets, columns, values;
};
CsrArrays transpose_csr(const torch::Tensor& offsets, const torch::Tensor& columns,
                        const torch::Tensor& values, int64_t cols) {
  const int64_t rows = offsets.size(0) - 1, nnz = columns.size(0);
  CsrArrays t{torch::zeros({cols + 1}, torch::kInt64), torch::empty({nnz}, torch::kInt64),
              torch::empty({nnz}, torch::kFloat32)};
  const int64_t* po = ptr(offsets);
  const int64_t* pc = ptr(columns);
  const float* pv = values.data_ptr<float>();
  int64_t* to = t.offsets.data_ptr<int64_t>();
  int64_t* tc = t.columns.data_ptr<int64_t>();
  float* tv = t.values.data_ptr<float>();
  for (int64_t q = 0; q < nnz; ++q) ++to[pc[q] + 1];
  for (int64_t c = 0; c < cols; ++c) to[c + 1] += to[c];
  std::vector<int64_t> next(to, to + cols);
  for (int64_t r = 0; r < rows; ++r) {
    for (int64_t q = po[r]; q < po[r + 1]; ++q) {
      const int64_t slot = next[pc[q]]++;
      tc[slot] = r;
      tv[slot] = pv[q];
    }
  }
  return t;
}

void check_edges(const torch::Tensor& t, const EdgeIndex& edges, const char* name, bool per_edge) {
  const int64_t expected = per_edge ? edges.num_edges() : edges.num_nodes;
  if (t.size(0) != expected) {
    throw InputError(std::string("graph kernel: ") + name + " has " + std::to_string(t.size(0)) +
                     " rows, expected " + std::to_string(expected) +
                     (per_edge ? " (one per edge)" : " (one per node)"));
  }
}

// Column sums of rows [0, rows) produced by body(begin, end, partial) over fixed blocks, so the
// result does not depend on the thread count. body adds its rows into partial [C].
template <class Body>
torch::Tensor blocked_column_sum(int64_t rows, int64_t channels, const Body& body) {
  const int64_t block = std::max<int64_t>(grain_rows(channels), (rows + 63) / 64);
  const int64_t blocks = std::max<int64_t>(1, (rows + block - 1) / block);
  auto partial = torch::zeros({blocks, channels}, torch::kFloat32);
  float* pp = partial.data_ptr<float>();
  at::parallel_for(0, blocks, 1, [&](int64_t b0, int64_t b1) {
    for (int64_t blk = b0; blk < b1; ++blk) {
      body(blk * block, std::min(rows, (blk + 1) * block), pp + blk * channels);
    }
  });
  return partial.sum(0);
}

// grad * (out > 0) into masked, returning the column sums of masked.
torch::Tensor relu_mask(const torch::Tensor& out, const torch::Tensor& grad,
                        torch::Tensor& masked) {
  const int64_t rows = out.size(0), channels = out.size(1);
  masked = torch::empty_like(grad);
  const float* po = out.data_ptr<float>();
  const float* pg = grad.data_ptr<float>();
  float* pm = masked.data_ptr<float>();
  return blocked_column_sum(rows, channels, [&](int64_t begin, int64_t end, float* sum) {
    relu_mask_rows(po, pg, begin, end, channels, pm, sum);
  });
}

struct EdgeFirstLayer : torch::autograd::Function<EdgeFirstLayer> {
  static torch::Tensor forward(AutogradContext* ctx, const torch::Tensor& base_in,
                               const torch::Tensor& features_in, const torch::Tensor& weight_in,
                               const torch::Tensor& bias_in, const torch::Tensor& a_in,
                               const torch::Tensor& b_in, const EdgeIndex& edges) {
    auto features = checked_float(features_in, "features");
    auto weight = checked_float(weight_in, "weight");
    auto a = checked_float(a_in, "a");
    auto b = checked_float(b_in, "b");
    auto bias = bias_in.contiguous();
    const bool has_base = base_in.dim() == 2;  // an empty 1-D tensor means "no base"
    torch::Tensor base = has_base ? checked_float(base_in, "base") : torch::Tensor();
    check_edges(features, edges, "features", true);
    check_edges(a, edges, "a", false);
    check_edges(b, edges, "b", false);
    const int64_t num_edges = features.size(0), channels = a.size(1), k = features.size(1);
    if (b.size(1) != channels || weight.size(0) != channels || weight.size(1) != k ||
        bias.numel() != channels ||
        (has_base && (base.size(0) != num_edges || base.size(1) != channels))) {
      throw InputError("graph kernel: edge_first_layer shape mismatch");
    }
    // weightᵀ [K, C] so that the inner loop runs over contiguous channels.
    auto wt = weight.t().contiguous();
    auto out = torch::empty({num_edges, channels}, a.options());
    const float* pbase = has_base ? base.data_ptr<float>() : nullptr;
    const float* pf = features.data_ptr<float>();
    const float* pw = wt.data_ptr<float>();
    const float* pbias = bias.data_ptr<float>();
    const float* pa = a.data_ptr<float>();
    const float* pb = b.data_ptr<float>();
    const int64_t* s = ptr(edges.senders);
    const int64_t* r = ptr(edges.receivers);
    float* po = out.data_ptr<float>();
    at::parallel_for(0, num_edges, grain_rows(channels), [&](int64_t begin, int64_t end) {
      for (int64_t e = begin; e < end; ++e) {
        edge_first_row(pbase ? pbase + e * channels : nullptr, pbias, pa + s[e] * channels,
                       pb + r[e] * channels, pf + e * k, pw, k, channels, po + e * channels);
      }
    });
    ctx->save_for_backward({out, features, weight});
    ctx->saved_data["has_base"] = has_base;
    ctx->saved_data["bf16"] = bf16_products();
    ctx->saved_data["sender_offsets"] = edges.sender_offsets;
    ctx->saved_data["sender_order"] = edges.sender_order;
    ctx->saved_data["receiver_offsets"] = edges.receiver_offsets;
    ctx->saved_data["receiver_order"] = edges.receiver_order;
    ctx->saved_data["num_nodes"] = edges.num_nodes;
    return out;
  }

  static variable_list backward(AutogradContext* ctx, variable_list grads) {
    auto saved = ctx->get_saved_variables();
    const auto& out = saved[0];
    const auto& features = saved[1];
    const auto& weight = saved[2];
    auto grad = grads[0].contiguous();
    torch::Tensor masked;
    auto grad_bias = relu_mask(out, grad, masked);
    const int64_t nodes = ctx->saved_data["num_nodes"].toInt();
    torch::Tensor grad_features, grad_weight, ga, gb;
    if (ctx->needs_input_grad(1))
      grad_features = gemm(masked, gemm_operand(weight, ctx->saved_data["bf16"].toBool()));
    if (ctx->needs_input_grad(2)) {
      // gradᵀ · features [C, K] with K the few edge features: BLAS's small-matrix path ran this
      // long, thin product at ~15 GFLOP/s on one thread; here as sums of per-edge outer products
      // [K, C] over fixed blocks of edges (the sum does not depend on the thread count).
      const int64_t channels = masked.size(1), k = features.size(1);
      const float* pg = masked.data_ptr<float>();
      const float* pf = features.data_ptr<float>();
      grad_weight = blocked_column_sum(masked.size(0), k * channels,
                                       [&](int64_t begin, int64_t end, float* sum) {
                                         for (int64_t e = begin; e < end; ++e)
                                           outer_accumulate_row(pg + e * channels, pf + e * k, k,
                                                                channels, sum);
                                       })
                        .view({k, channels})
                        .t()
                        .contiguous();
    }
    if (ctx->needs_input_grad(4)) {
      ga = segment_sum_tensor(masked, ctx->saved_data["sender_offsets"].toTensor(),
                              ctx->saved_data["sender_order"].toTensor(), nodes);
    }
    if (ctx->needs_input_grad(5)) {
      gb = segment_sum_tensor(masked, ctx->saved_data["receiver_offsets"].toTensor(),
                              ctx->saved_data["receiver_order"].toTensor(), nodes);
    }
    const bool has_base = ctx->saved_data["has_base"].toBool();
    return {has_base ? masked : torch::Tensor(),
            grad_features,
            grad_weight,
            grad_bias,
            ga,
            gb,
            torch::Tensor()};
  }
};

// Runs fn(begin, end) over [0, rows) in blocks of at least min_rows, one block per thread. The
// caller's thread-local state (grad and inference mode) is set on the workers, which call ATen.
template <class Fn>
void parallel_blocks(int64_t rows, int64_t min_rows, const Fn& fn) {
  const int64_t threads = at::in_parallel_region() ? 1 : at::get_num_threads();
  const int64_t blocks =
      std::max<int64_t>(1, std::min(threads, rows / std::max<int64_t>(1, min_rows)));
  if (blocks == 1) {
    fn(0, rows);
    return;
  }
  const int64_t block = (rows + blocks - 1) / blocks;
  const at::ThreadLocalState state;
  at::parallel_for(0, blocks, 1, [&](int64_t b0, int64_t b1) {
    const at::ThreadLocalStateGuard guard(state);
    for (int64_t b = b0; b < b1; ++b) fn(b * block, std::min(rows, (b + 1) * block));
  });
}

// Rows per block of a weight gradient (a sum over fixed blocks: thread-count independent).
constexpr int64_t kMinWeightGradRows = 128;
// Fewest rows a worker of a forward GEMM (or of an input gradient) takes: small graphs (a ~400-node
// mesh and its coarse levels) are split over the threads too; row blocks do not change any row's
// result.
constexpr int64_t kMinForwardRows = 32;
// Fewest edges a worker of the tiled edge kernels takes: small edge sets (contacts, coarse levels)
// are split too, in tiles shorter than kTile.
constexpr int64_t kMinPartEdges = 32;

struct LinearFn : torch::autograd::Function<LinearFn> {
  static torch::Tensor forward(AutogradContext* ctx, const torch::Tensor& x_in,
                               const torch::Tensor& weight_in, const torch::Tensor& bias_in,
                               bool relu) {
    // Detached: the blocks call ATen ops with out= arguments, which refuse tensors needing grad.
    auto x = checked_float(x_in, "x").detach();
    auto weight = checked_float(weight_in, "weight").detach();
    const int64_t rows = x.size(0), out_size = weight.size(0);
    if (weight.size(1) != x.size(1)) {
      throw InputError("linear: input has " + std::to_string(x.size(1)) +
                       " channels, weight expects " + std::to_string(weight.size(1)));
    }
    const bool has_bias = bias_in.dim() == 1;  // a 0-D tensor means "no bias"
    auto bias = has_bias ? bias_in.contiguous() : torch::Tensor();
    if (has_bias && bias.numel() != out_size) throw InputError("linear: bias size mismatch");
    auto y = torch::empty({rows, out_size}, x.options());
    const auto wt = gemm_operand(weight.t());
    const float* pb = has_bias ? bias.data_ptr<float>() : nullptr;
    parallel_blocks(rows, kMinForwardRows, [&](int64_t r0, int64_t r1) {
      auto yb = y.slice(0, r0, r1);
      gemm_out(yb, x.slice(0, r0, r1), wt);
      if (pb || relu) bias_relu_rows(y.data_ptr<float>(), pb, relu, r0, r1, out_size);
    });
    ctx->save_for_backward({x, weight, relu ? y : torch::Tensor()});
    ctx->saved_data["relu"] = relu;
    ctx->saved_data["bf16"] = bf16_products();  // the backward's products as the forward's
    ctx->saved_data["has_bias"] = has_bias;
    return y;
  }

  static variable_list backward(AutogradContext* ctx, variable_list grads) {
    auto saved = ctx->get_saved_variables();
    const auto x = saved[0].detach();
    const auto weight = saved[1].detach();
    const bool relu = ctx->saved_data["relu"].toBool();
    const bool has_bias = ctx->saved_data["has_bias"].toBool();
    const bool bf16 = ctx->saved_data["bf16"].toBool();
    auto grad = grads[0].contiguous().detach();
    torch::Tensor grad_bias;
    if (relu) {
      torch::Tensor masked;
      grad_bias = relu_mask(saved[2], grad, masked);
      grad = masked;
    } else if (has_bias && ctx->needs_input_grad(2)) {
      const float* pg = grad.data_ptr<float>();
      const int64_t channels = grad.size(1);
      grad_bias = blocked_column_sum(grad.size(0), channels, [&](int64_t b, int64_t e, float* s) {
        column_sum_rows(pg, b, e, channels, s);
      });
    }
    torch::Tensor grad_x, grad_weight;
    if (ctx->needs_input_grad(0)) {
      grad_x = torch::empty_like(x);
      const auto w = gemm_operand(weight, bf16);
      parallel_blocks(x.size(0), kMinForwardRows, [&](int64_t r0, int64_t r1) {
        auto gb = grad_x.slice(0, r0, r1);
        gemm_out(gb, grad.slice(0, r0, r1), w);
      });
    }
    if (ctx->needs_input_grad(1)) {
      // dW = gradᵀ x as a sum over fixed blocks of rows (so the result does not depend on the
      // thread count): each GEMM packs only its own rows of grad and x, where splitting dW over
      // output channels would make every thread pack all of x.
      const int64_t rows = x.size(0);
      const int64_t block = std::max<int64_t>(kMinWeightGradRows, (rows + 7) / 8);
      const int64_t blocks = std::max<int64_t>(1, (rows + block - 1) / block);
      auto partial = torch::empty({blocks, weight.size(0), weight.size(1)}, weight.options());
      parallel_blocks(blocks, 1, [&](int64_t b0, int64_t b1) {
        for (int64_t blk = b0; blk < b1; ++blk) {
          const int64_t r0 = blk * block, r1 = std::min(rows, r0 + block);
          auto gw = partial[blk];
          const auto xb = x.slice(0, r0, r1);
          gemm_out(gw, grad.slice(0, r0, r1).t(), gemm_operand(xb, bf16));
        }
      });
      grad_weight = blocks == 1 ? partial[0] : partial.sum(0);
    }
    return {grad_x, grad_weight, has_bias ? grad_bias : torch::Tensor(), torch::Tensor()};
  }
};

struct LayerNormSegmentSum : torch::autograd::Function<LayerNormSegmentSum> {
  static torch::Tensor forward(AutogradContext* ctx, const torch::Tensor& x_in,
                               const torch::Tensor& bias_in, const EdgeIndex& edges) {
    auto x = checked_float(x_in, "x");
    auto bias = bias_in.contiguous();
    check_edges(x, edges, "x", true);
    const int64_t num_edges = x.size(0), channels = x.size(1), nodes = edges.num_nodes;
    if (bias.numel() != channels) throw InputError("graph kernel: layer norm bias size mismatch");
    const float* pbias = bias.data_ptr<float>();
    auto out = torch::empty({nodes, channels}, x.options());
    auto stats = torch::empty({num_edges, 2}, x.options());  // mean, 1/std per edge
    const float* px = x.data_ptr<float>();
    float* po = out.data_ptr<float>();
    float* ps = stats.data_ptr<float>();
    const int64_t* off = ptr(edges.receiver_offsets);
    const int64_t* order = ptr(edges.receiver_order);
    at::parallel_for(0, nodes, grain_rows(channels) / 4 + 1, [&](int64_t begin, int64_t end) {
      for (int64_t j = begin; j < end; ++j) {
        float* o = po + j * channels;
        std::fill(o, o + channels, 0.0f);
        for (int64_t q = off[j]; q < off[j + 1]; ++q) {
          const int64_t e = order[q];
          layer_norm_accumulate_row(px + e * channels, pbias, channels, kLayerNormEps, ps + 2 * e,
                                    o);
        }
      }
    });
    ctx->save_for_backward({x, bias, stats});
    ctx->saved_data["receivers"] = edges.receivers;
    return out;
  }

  static variable_list backward(AutogradContext* ctx, variable_list grads) {
    auto saved = ctx->get_saved_variables();
    const auto& x = saved[0];
    const auto& bias = saved[1];
    const auto& stats = saved[2];
    auto grad = grads[0].contiguous();
    auto receivers = ctx->saved_data["receivers"].toTensor();
    const int64_t num_edges = x.size(0), channels = x.size(1);
    auto dx = torch::empty_like(x);
    const float* px = x.data_ptr<float>();
    const float* pbias = bias.data_ptr<float>();
    const float* ps = stats.data_ptr<float>();
    const float* pg = grad.data_ptr<float>();
    const int64_t* r = ptr(receivers);
    float* pd = dx.data_ptr<float>();
    auto grad_bias =
        blocked_column_sum(num_edges, channels, [&](int64_t begin, int64_t end, float* sum_d) {
          for (int64_t e = begin; e < end; ++e) {
            layer_norm_backward_row(px + e * channels, pbias, pg + r[e] * channels, ps + 2 * e,
                                    channels, pd + e * channels, sum_d);
          }
        });
    return {dx, grad_bias, torch::Tensor()};
  }
};

struct SegmentSum : torch::autograd::Function<SegmentSum> {
  static torch::Tensor forward(AutogradContext* ctx, const torch::Tensor& x_in,
                               const EdgeIndex& edges) {
    auto x = checked_float(x_in, "x");
    check_edges(x, edges, "x", true);
    ctx->saved_data["receivers"] = edges.receivers;
    return segment_sum_tensor(x, edges.receiver_offsets, edges.receiver_order, edges.num_nodes);
  }

  static variable_list backward(AutogradContext* ctx, variable_list grads) {
    return {grads[0].index_select(0, ctx->saved_data["receivers"].toTensor()), torch::Tensor()};
  }
};

// Sparse product with a transition matrix (down: D v) or its transpose (up: Dᵀ v).
struct SparseTransition : torch::autograd::Function<SparseTransition> {
  static torch::Tensor forward(AutogradContext* ctx, const torch::Tensor& v_in,
                               const LevelTransition& t, bool up) {
    auto v = checked_float(v_in, "v");
    const int64_t in_rows = up ? t.coarse_nodes : t.fine_nodes;
    if (v.size(0) != in_rows) {
      throw InputError("transition: input has " + std::to_string(v.size(0)) + " rows, expected " +
                       std::to_string(in_rows) + (up ? " (coarse nodes)" : " (fine nodes)"));
    }
    ctx->saved_data["up"] = up;
    ctx->saved_data["transpose"] = t.up_is_down_transpose;
    ctx->saved_data["down_offsets"] = t.down_offsets;
    ctx->saved_data["down_columns"] = t.down_columns;
    ctx->saved_data["down_values"] = t.down_values;
    ctx->saved_data["up_offsets"] = t.up_offsets;
    ctx->saved_data["up_columns"] = t.up_columns;
    ctx->saved_data["up_values"] = t.up_values;
    ctx->saved_data["fine"] = t.fine_nodes;
    ctx->saved_data["coarse"] = t.coarse_nodes;
    return up ? sparse_rows(v, t.up_offsets, t.up_columns, t.up_values, t.fine_nodes)
              : sparse_rows(v, t.down_offsets, t.down_columns, t.down_values, t.coarse_nodes);
  }

  static variable_list backward(AutogradContext* ctx, variable_list grads) {
    auto& d = ctx->saved_data;
    const bool up = d["up"].toBool();
    const int64_t rows = up ? d["coarse"].toInt() : d["fine"].toInt();
    if (!d["transpose"].toBool()) {
      // Up is not Dᵀ: the adjoint of the matrix used in forward, transposed here.
      const std::string p = up ? "up_" : "down_";
      auto at = transpose_csr(d[p + "offsets"].toTensor(), d[p + "columns"].toTensor(),
                              d[p + "values"].toTensor(), rows);
      return {sparse_rows(grads[0], at.offsets, at.columns, at.values, rows), torch::Tensor(),
              torch::Tensor()};
    }
    // The adjoint of D is Dᵀ and vice versa.
    const std::string p = up ? "down_" : "up_";
    auto g = sparse_rows(grads[0], d[p + "offsets"].toTensor(), d[p + "columns"].toTensor(),
                         d[p + "values"].toTensor(), rows);
    return {g, torch::Tensor(), torch::Tensor()};
  }
};

// The checked inputs of the tiled inference kernels: rows x [E, K] (edge features or latents),
// per-node projections a, b [N, C] and the edge MLP's weights w1 [C, K], w2, w3 [C, C], biases [C].
struct TiledEdgeMlp {
  torch::Tensor x, a, b, w1, w2, w3, b1, b2, b3;
  int64_t channels = 0, k = 0, nodes = 0;
  bool ends_per_edge = false;  // a [E, C] per edge, b one zero row
};

TiledEdgeMlp checked_tiled_edge_mlp(const char* kernel, const char* x_name,
                                    const torch::Tensor& x_in, const torch::Tensor& w1_in,
                                    const torch::Tensor& b1_in, const torch::Tensor& a_in,
                                    const torch::Tensor& b_in, const torch::Tensor& w2_in,
                                    const torch::Tensor& b2_in, const torch::Tensor& w3_in,
                                    const torch::Tensor& b3_in, const EdgeIndex& edges,
                                    bool square_first_layer) {
  const std::string name(kernel);
  if (torch::GradMode::is_enabled()) {
    for (const auto* t : {&x_in, &w1_in, &b1_in, &a_in, &b_in, &w2_in, &b2_in, &w3_in, &b3_in}) {
      if (t->defined() && t->requires_grad())
        throw InputError("graph kernel: " + name + " is for inference (no gradients)");
    }
  }
  TiledEdgeMlp m;
  m.x = checked_float(x_in, x_name);
  m.a = checked_float(a_in, "a");
  // No b: a holds both endpoint terms of each edge (one row per edge).
  m.ends_per_edge = !b_in.defined();
  m.b = m.ends_per_edge ? torch::zeros({1, m.a.size(1)}, m.a.options()) : checked_float(b_in, "b");
  m.w1 = checked_float(w1_in, "w1");
  m.w2 = checked_float(w2_in, "w2");
  m.w3 = checked_float(w3_in, "w3");
  m.b1 = b1_in.contiguous();
  m.b2 = b2_in.contiguous();
  m.b3 = b3_in.contiguous();
  check_edges(m.x, edges, x_name, true);
  check_edges(m.a, edges, "a", m.ends_per_edge);
  if (!m.ends_per_edge) check_edges(m.b, edges, "b", false);
  const int64_t c = m.a.size(1), k = m.x.size(1);
  if (m.b.size(1) != c || m.w1.size(0) != c || m.w1.size(1) != k || m.b1.numel() != c ||
      m.w2.size(0) != c || m.w2.size(1) != c || m.b2.numel() != c || m.w3.size(0) != c ||
      m.w3.size(1) != c || m.b3.numel() != c || (square_first_layer && k != c)) {
    throw InputError("graph kernel: " + name + " shape mismatch");
  }
  m.channels = c;
  m.k = k;
  m.nodes = edges.num_nodes;
  return m;
}

// Receiver ranges [bounds[p], bounds[p+1]) holding about equal numbers of edges, one per worker
// (at most one per `min_edges` edges), so each worker alone adds to its receivers' output rows.
std::vector<int64_t> receiver_ranges(const int64_t* off, int64_t nodes, int64_t min_edges) {
  const int64_t threads = at::in_parallel_region() ? 1 : at::get_num_threads();
  const int64_t parts = std::max<int64_t>(1, std::min<int64_t>(threads, off[nodes] / min_edges));
  std::vector<int64_t> bounds(parts + 1, nodes);
  for (int64_t p = 0; p < parts; ++p)
    bounds[p] = std::lower_bound(off, off + nodes + 1, off[nodes] * p / parts) - off;
  bounds[0] = 0;
  return bounds;
}

}  // namespace

torch::Tensor edge_first_layer(const torch::Tensor& base, const torch::Tensor& features,
                               const torch::Tensor& weight, const torch::Tensor& bias,
                               const torch::Tensor& a, const torch::Tensor& b,
                               const EdgeIndex& edges) {
  RECORD_FUNCTION("bsms::edge_first_layer", std::vector<c10::IValue>());
  // Custom functions take no undefined inputs: an empty 1-D tensor stands for "no base".
  return EdgeFirstLayer::apply(base.defined() ? base : torch::empty({0}), features, weight, bias, a,
                               b, edges);
}

torch::Tensor edge_mlp_segment_sum(const torch::Tensor& features_in, const torch::Tensor& w1_in,
                                   const torch::Tensor& b1_in, const torch::Tensor& a_in,
                                   const torch::Tensor& b_in, const torch::Tensor& w2_in,
                                   const torch::Tensor& b2_in, const torch::Tensor& w3_in,
                                   const torch::Tensor& b3_in, const EdgeIndex& edges) {
  RECORD_FUNCTION("bsms::edge_mlp_segment_sum", std::vector<c10::IValue>());
  const TiledEdgeMlp m =
      checked_tiled_edge_mlp("edge_mlp_segment_sum", "features", features_in, w1_in, b1_in, a_in,
                             b_in, w2_in, b2_in, w3_in, b3_in, edges, false);
  const auto &features = m.x, &a = m.a, &b = m.b, &w1 = m.w1, &w2 = m.w2, &w3 = m.w3;
  const auto &b1 = m.b1, &b2 = m.b2, &b3 = m.b3;
  const int64_t channels = m.channels, k = m.k, nodes = m.nodes;
  auto w1t = w1.t().contiguous();  // [K, C]: the inner loop runs over contiguous channels
  const auto w2t = gemm_operand(w2.t()), w3t = gemm_operand(w3.t());
  auto out = torch::zeros({nodes, channels}, a.options());
  const float* pf = features.data_ptr<float>();
  const float* pw1 = w1t.data_ptr<float>();
  const float* pa = a.data_ptr<float>();
  const float* pb = b.data_ptr<float>();
  const float* pb1 = b1.data_ptr<float>();
  const float* pb2 = b2.data_ptr<float>();
  const float* pb3 = b3.data_ptr<float>();
  const int64_t* s = ptr(edges.senders);
  const int64_t* r = ptr(edges.receivers);
  const int64_t* off = ptr(edges.receiver_offsets);
  const int64_t* order = ptr(edges.receiver_order);
  float* po = out.data_ptr<float>();
  constexpr int64_t kTile = 256;  // edges per tile: three [256, C] buffers stay in L2
  // Each worker owns a range of receivers holding about the same number of edges, so it alone
  // adds to their output rows.
  const std::vector<int64_t> bounds = receiver_ranges(off, nodes, kMinPartEdges);
  const int64_t parts = static_cast<int64_t>(bounds.size()) - 1;
  parallel_blocks(parts, 1, [&](int64_t p0, int64_t p1) {
    auto h1 = torch::empty({kTile, channels}, a.options());
    auto h2 = torch::empty({kTile, channels}, a.options());
    auto y = torch::empty({kTile, channels}, a.options());
    float* ph1 = h1.data_ptr<float>();
    float* ph2 = h2.data_ptr<float>();
    float* py = y.data_ptr<float>();
    float stats[2];
    const int64_t j0 = bounds[p0], j1 = bounds[p1];
    for (int64_t q0 = off[j0]; q0 < off[j1]; q0 += kTile) {
      const int64_t n = std::min(kTile, off[j1] - q0);
      for (int64_t t = 0; t < n; ++t) {
        const int64_t e = order[q0 + t];
        const float* ends_a = m.ends_per_edge ? pa + e * channels : pa + s[e] * channels;
        const float* ends_b = m.ends_per_edge ? pb : pb + r[e] * channels;
        edge_first_row(nullptr, pb1, ends_a, ends_b, pf + e * k, pw1, k, channels,
                       ph1 + t * channels);
      }
      auto h2n = h2.narrow(0, 0, n);
      gemm_out(h2n, h1.narrow(0, 0, n), w2t);
      bias_relu_rows(ph2, pb2, true, 0, n, channels);
      auto yn = y.narrow(0, 0, n);
      gemm_out(yn, h2n, w3t);
      for (int64_t t = 0; t < n; ++t) {
        const int64_t e = order[q0 + t];
        layer_norm_accumulate_row(py + t * channels, pb3, channels, kLayerNormEps, stats,
                                  po + r[e] * channels);
      }
    }
  });
  return out;
}

torch::Tensor edge_latent_update(const torch::Tensor& latent_in, const torch::Tensor& w1_in,
                                 const torch::Tensor& b1_in, const torch::Tensor& a_in,
                                 const torch::Tensor& b_in, const torch::Tensor& w2_in,
                                 const torch::Tensor& b2_in, const torch::Tensor& w3_in,
                                 const torch::Tensor& b3_in, const EdgeIndex& edges,
                                 torch::Tensor& latent_out) {
  RECORD_FUNCTION("bsms::edge_latent_update", std::vector<c10::IValue>());
  const TiledEdgeMlp m =
      checked_tiled_edge_mlp("edge_latent_update", "latent", latent_in, w1_in, b1_in, a_in, b_in,
                             w2_in, b2_in, w3_in, b3_in, edges, true);
  if (m.ends_per_edge) throw InputError("graph kernel: edge_latent_update needs b (one per node)");
  const auto &latent = m.x, &a = m.a, &b = m.b, &w1 = m.w1, &w2 = m.w2, &w3 = m.w3;
  const auto &b1 = m.b1, &b2 = m.b2, &b3 = m.b3;
  const int64_t channels = m.channels, k = m.k, nodes = m.nodes;
  const auto w1t = gemm_operand(w1.t()), w2t = gemm_operand(w2.t()), w3t = gemm_operand(w3.t());
  auto out = torch::zeros({nodes, channels}, a.options());
  latent_out = torch::empty_like(latent);
  const float* pl = latent.data_ptr<float>();
  const float* pa = a.data_ptr<float>();
  const float* pb = b.data_ptr<float>();
  const float* pb1 = b1.data_ptr<float>();
  const float* pb2 = b2.data_ptr<float>();
  const float* pb3 = b3.data_ptr<float>();
  const int64_t* s = ptr(edges.senders);
  const int64_t* r = ptr(edges.receivers);
  const int64_t* off = ptr(edges.receiver_offsets);
  const int64_t* order = ptr(edges.receiver_order);
  float* po = out.data_ptr<float>();
  float* plo = latent_out.data_ptr<float>();
  constexpr int64_t kTile = 256;
  const std::vector<int64_t> bounds = receiver_ranges(off, nodes, kMinPartEdges);
  const int64_t parts = static_cast<int64_t>(bounds.size()) - 1;
  parallel_blocks(parts, 1, [&](int64_t p0, int64_t p1) {
    auto g = torch::empty({kTile, k}, a.options());
    auto h1 = torch::empty({kTile, channels}, a.options());
    auto h2 = torch::empty({kTile, channels}, a.options());
    float* pg = g.data_ptr<float>();
    float* ph1 = h1.data_ptr<float>();
    float* ph2 = h2.data_ptr<float>();
    const int64_t j0 = bounds[p0], j1 = bounds[p1];
    for (int64_t q0 = off[j0]; q0 < off[j1]; q0 += kTile) {
      const int64_t n = std::min(kTile, off[j1] - q0);
      for (int64_t t = 0; t < n; ++t) {
        const int64_t e = order[q0 + t];
        std::copy(pl + e * k, pl + (e + 1) * k, pg + t * k);
      }
      auto h1n = h1.narrow(0, 0, n);
      gemm_out(h1n, g.narrow(0, 0, n), w1t);
      for (int64_t t = 0; t < n; ++t) {
        const int64_t e = order[q0 + t];
        float* o = ph1 + t * channels;
        const float* as = pa + s[e] * channels;
        const float* br = pb + r[e] * channels;
#pragma omp simd
        for (int64_t c = 0; c < channels; ++c) o[c] = relu_value(o[c] + pb1[c] + as[c] + br[c]);
      }
      auto h2n = h2.narrow(0, 0, n);
      gemm_out(h2n, h1n, w2t);
      bias_relu_rows(ph2, pb2, true, 0, n, channels);
      gemm_out(h1n, h2n, w3t);  // h1 reused for the last layer's output
      for (int64_t t = 0; t < n; ++t) {
        const int64_t e = order[q0 + t];
        const float* y = ph1 + t * channels;
        const LayerNormStats st = layer_norm_stats(y, pb3, channels, kLayerNormEps);
        float* acc = po + r[e] * channels;
        float* lo = plo + e * channels;
        const float* li = pl + e * channels;
#pragma omp simd
        for (int64_t c = 0; c < channels; ++c) {
          const float v = (y[c] + pb3[c] - st.mean) * st.rstd;
          acc[c] += v;
          lo[c] = li[c] + v;
        }
      }
    }
  });
  return out;
}

torch::Tensor linear(const torch::Tensor& x, const torch::Tensor& weight, const torch::Tensor& bias,
                     bool relu) {
  RECORD_FUNCTION("bsms::linear", std::vector<c10::IValue>());
  if (!torch::GradMode::is_enabled()) return mlp_inference({x}, {{weight, bias, relu}}, false, {});
  return LinearFn::apply(x, weight, bias.defined() ? bias : torch::empty({}), relu);
}

namespace {

// mlp_inference's input parts, checked: x per part (detached), the row indices of each sparse
// part (undefined for dense ones), the summed channels and the row count.
struct MlpInputs {
  std::vector<torch::Tensor> x, at_rows;
  int64_t channels = 0, rows = 0;
};

MlpInputs mlp_inputs(const std::vector<torch::Tensor>& parts,
                     const std::vector<torch::Tensor>& part_rows) {
  if (!part_rows.empty() && (part_rows.size() != parts.size() || part_rows[0].defined()))
    throw InputError("mlp_inference: part_rows needs one entry per part, the first one dense");
  MlpInputs in;
  std::vector<torch::Tensor>& x = in.x;
  std::vector<torch::Tensor>& at_rows = in.at_rows;
  at_rows.resize(parts.size());
  for (size_t p = 0; p < parts.size(); ++p) {
    x.push_back(checked_float(parts[p], "x").detach());
    const bool sparse = p < part_rows.size() && part_rows[p].defined();
    if (sparse) {
      at_rows[p] = part_rows[p].to(torch::kInt64).contiguous();
      if (at_rows[p].dim() != 1 || at_rows[p].size(0) != x.back().size(0))
        throw InputError("mlp_inference: a sparse part needs one row index per value row");
    } else if (x.back().size(0) != x.front().size(0)) {
      throw InputError("mlp_inference: input parts have different row counts");
    }
    in.channels += x.back().size(1);
  }
  const int64_t rows = in.rows = x.front().size(0);
  for (const auto& r : at_rows) {
    if (!r.defined() || r.numel() == 0) continue;
    const int64_t* pr = r.data_ptr<int64_t>();
    if (!std::is_sorted(pr, pr + r.numel()) || pr[0] < 0 || pr[r.numel() - 1] >= rows ||
        std::adjacent_find(pr, pr + r.numel()) != pr + r.numel())
      throw InputError("mlp_inference: sparse part rows must be distinct, ascending and < " +
                       std::to_string(rows));
  }
  return in;
}

// Per layer: the transposed weight (a view), its bias pointer (or null) and its width.
struct MlpWeights {
  std::vector<torch::Tensor> wt, bias;
  std::vector<const float*> pb;
  int64_t width = 0, widest = 0;  // the output's channels, the widest layer's
};

MlpWeights mlp_weights(const std::vector<DenseLayer>& layers, int64_t in, bool layer_norm) {
  MlpWeights m;
  int64_t width = in, widest = 0;
  for (const auto& layer : layers) {
    const auto w = checked_float(layer.weight, "weight").detach();
    if (w.size(1) != width)
      throw InputError("linear: input has " + std::to_string(width) + " channels, weight expects " +
                       std::to_string(w.size(1)));
    width = w.size(0);
    widest = std::max(widest, width);
    m.wt.push_back(gemm_operand(w.t()));
    const bool has_bias = layer.bias.defined() && layer.bias.dim() == 1;
    if (has_bias && layer.bias.numel() != width) throw InputError("linear: bias size mismatch");
    m.bias.push_back(has_bias ? layer.bias.detach().contiguous() : torch::Tensor());
    m.pb.push_back(has_bias ? m.bias.back().data_ptr<float>() : nullptr);
  }
  if (layer_norm && !m.pb.back()) throw InputError("mlp_inference: layer norm needs the last bias");
  m.width = width;
  m.widest = widest;
  return m;
}

}  // namespace

torch::Tensor mlp_inference(const std::vector<torch::Tensor>& parts,
                            const std::vector<DenseLayer>& layers, bool layer_norm,
                            const std::vector<torch::Tensor>& part_rows) {
  RECORD_FUNCTION("bsms::mlp_inference", std::vector<c10::IValue>());
  if (parts.empty() || layers.empty())
    throw InputError("mlp_inference: needs at least one input part and one layer");
  const MlpInputs inputs = mlp_inputs(parts, part_rows);
  const std::vector<torch::Tensor>& x = inputs.x;
  const std::vector<torch::Tensor>& at_rows = inputs.at_rows;
  const int64_t rows = inputs.rows;
  const MlpWeights weights = mlp_weights(layers, inputs.channels, layer_norm);
  const std::vector<torch::Tensor>& wt = weights.wt;
  const std::vector<const float*>& pb = weights.pb;
  const int64_t width = weights.width, widest = weights.widest;
  auto y = torch::empty({rows, width}, x.front().options().requires_grad(false));
  const size_t last = layers.size() - 1;
  // Each worker takes a block of rows through every layer (no join between layers); hidden
  // activations live in two per-worker buffers.
  parallel_blocks(rows, kMinForwardRows, [&](int64_t r0, int64_t r1) {
    const int64_t n = r1 - r0;
    torch::Tensor h[2];
    if (last > 0) {
      h[0] = torch::empty({n, widest}, y.options());
      if (last > 1) h[1] = torch::empty({n, widest}, y.options());
    }
    torch::Tensor in_block;
    for (size_t l = 0; l <= last; ++l) {
      const int64_t out = wt[l].size(1);
      torch::Tensor o =
          l == last ? y.slice(0, r0, r1) : h[l % 2].view(-1).narrow(0, 0, n * out).view({n, out});
      if (l == 0) {
        // The first layer over the column parts: Σ_p x_p · (its rows of wᵀ), no concatenation;
        // a sparse part adds to its rows only.
        int64_t col = 0;
        for (size_t p = 0; p < x.size(); ++p) {
          const int64_t k = x[p].size(1);
          const auto wp = wt[0].narrow(0, col, k);
          col += k;
          if (!at_rows[p].defined()) {
            const auto xp = x[p].slice(0, r0, r1);
            if (p == 0)
              gemm_out(o, xp, wp);
            else
              gemm_add(o, xp, wp);
            continue;
          }
          const int64_t* pr = at_rows[p].data_ptr<int64_t>();
          const int64_t count = at_rows[p].numel();
          const int64_t q0 = std::lower_bound(pr, pr + count, r0) - pr;
          const int64_t q1 = std::lower_bound(pr, pr + count, r1) - pr;
          if (q1 == q0) continue;
          const auto add = gemm(x[p].slice(0, q0, q1), wp);
          const float* pa = add.data_ptr<float>();
          float* po = o.data_ptr<float>();
          for (int64_t q = q0; q < q1; ++q) {
            float* row = po + (pr[q] - r0) * out;
            const float* src = pa + (q - q0) * out;
            for (int64_t c = 0; c < out; ++c) row[c] += src[c];
          }
        }
      } else {
        gemm_out(o, in_block, wt[l]);
      }
      float* po = o.data_ptr<float>();
      if (l == last && layer_norm)
        bias_layer_norm_rows(po, pb[l], 0, n, out, kLayerNormEps);
      else if (pb[l] || layers[l].relu)
        bias_relu_rows(po, pb[l], layers[l].relu, 0, n, out);
      in_block = o;
    }
  });
  return y;
}

void set_matmul_precision(MatmulPrecision precision) {
  g_matmul_precision.store(static_cast<int>(precision), std::memory_order_relaxed);
}

std::string matmul_library() {
  static const std::pair<dnnl_cpu_isa_t, const char*> kIsas[] = {
      {dnnl_cpu_isa_sse41, "sse41"},
      {dnnl_cpu_isa_avx, "avx"},
      {dnnl_cpu_isa_avx2, "avx2"},
      {dnnl_cpu_isa_avx2_vnni, "avx2_vnni"},
      {dnnl_cpu_isa_avx512_core, "avx512_core"},
      {dnnl_cpu_isa_avx512_core_vnni, "avx512_core_vnni"},
      {dnnl_cpu_isa_avx512_core_bf16, "avx512_core_bf16"},
      {dnnl_cpu_isa_avx512_core_amx, "avx512_core_amx"}};
  const dnnl_cpu_isa_t effective = dnnl_get_effective_cpu_isa();
  std::string isa = "isa " + std::to_string(static_cast<int>(effective));
  for (const auto& [value, name] : kIsas)
    if (value == effective) isa = name;
  const dnnl_version_t* v = dnnl_version();
  return "oneDNN " + std::to_string(v->major) + "." + std::to_string(v->minor) + "." +
         std::to_string(v->patch) + " sgemm, " + isa;
}

MatmulPrecision matmul_precision() {
  return static_cast<MatmulPrecision>(g_matmul_precision.load(std::memory_order_relaxed));
}

int configure_threads(int threads) {
  if (threads > 0) torch::set_num_threads(threads);
  single_threaded_blas();
  return torch::get_num_threads();
}

torch::Tensor layer_norm_segment_sum(const torch::Tensor& x, const torch::Tensor& bias,
                                     const EdgeIndex& edges) {
  RECORD_FUNCTION("bsms::layer_norm_segment_sum", std::vector<c10::IValue>());
  return LayerNormSegmentSum::apply(x, bias, edges);
}

torch::Tensor segment_sum(const torch::Tensor& x, const EdgeIndex& edges) {
  RECORD_FUNCTION("bsms::segment_sum", std::vector<c10::IValue>());
  return SegmentSum::apply(x, edges);
}

torch::Tensor transition_down(const torch::Tensor& v, const LevelTransition& transition) {
  RECORD_FUNCTION("bsms::transition_down", std::vector<c10::IValue>());
  return SparseTransition::apply(v, transition, false);
}

torch::Tensor transition_up(const torch::Tensor& v, const LevelTransition& transition) {
  RECORD_FUNCTION("bsms::transition_up", std::vector<c10::IValue>());
  return SparseTransition::apply(v, transition, true);
}

}  // namespace bsms
