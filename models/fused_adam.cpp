#include "models/fused_adam.hpp"

#include <ATen/Parallel.h>
#include <c10/util/string_utils.h>
#include <torch/autograd.h>

#include <cmath>
#include <string>

namespace bsms {
namespace {

// Elements per task of the parallel loop: below this a tensor is updated by one thread (the
// biases and LayerNorm vectors), above it the work is split (the weight matrices).
constexpr int64_t kGrain = 16384;

struct AdamScalars {
  float b1, a1, b2, a2, root2, eps, step_size;
};

// One pass over n elements; the arrays never overlap (a parameter, its gradient and its two
// moments are separate tensors), which lets the compiler vectorise the loop.
void adam_update(float* __restrict param, const float* __restrict g, float* __restrict m,
                 float* __restrict v, int64_t n, const AdamScalars k) {
  for (int64_t i = 0; i < n; ++i) {
    const float gi = g[i];
    const float mi = m[i] * k.b1 + k.a1 * gi;
    const float vi = v[i] * k.b2 + k.a2 * gi * gi;
    m[i] = mi;
    v[i] = vi;
    param[i] += k.step_size * mi / (std::sqrt(vi) / k.root2 + k.eps);
  }
}

std::string state_key(const torch::Tensor& p) {
  return c10::guts::to_string(p.unsafeGetTensorImpl());
}

}  // namespace

// The tensors of one fused update: a parameter, its gradient and its state (null before the
// parameter's first step).
struct FusedAdam::Slot {
  torch::Tensor param, grad;
  torch::optim::AdamParamState* state;
  std::string key;
  const torch::optim::AdamOptions* options;  // its group's
};

bool FusedAdam::collect(std::vector<Slot>& slots) {
  for (auto& group : param_groups()) {
    const auto& o = static_cast<const torch::optim::AdamOptions&>(group.options());
    if (o.weight_decay() != 0 || o.amsgrad()) return false;
    for (const auto& p : group.params()) {
      const auto& g = p.grad();
      if (!g.defined()) continue;
      if (p.scalar_type() != at::kFloat || g.scalar_type() != at::kFloat || g.is_sparse() ||
          !p.is_contiguous() || !g.is_contiguous() || !p.device().is_cpu() ||
          !g.device().is_cpu() || g.numel() != p.numel())
        return false;
      std::string key = state_key(p);
      const auto it = state().find(key);
      torch::optim::AdamParamState* s = nullptr;
      if (it != state().end()) {
        s = static_cast<torch::optim::AdamParamState*>(it->second.get());
        if (!s->exp_avg().is_contiguous() || !s->exp_avg_sq().is_contiguous() ||
            s->exp_avg().scalar_type() != at::kFloat ||
            s->exp_avg_sq().scalar_type() != at::kFloat || s->exp_avg().numel() != p.numel() ||
            s->exp_avg_sq().numel() != p.numel())
          return false;
      }
      slots.push_back(Slot{p, g, s, std::move(key), &o});
    }
  }
  return true;
}

torch::Tensor FusedAdam::step(LossClosure closure) {
  torch::NoGradGuard no_grad;
  torch::Tensor loss;
  if (closure != nullptr) {
    at::AutoGradMode enable_grad(true);
    loss = closure();
  }
  // Everything is checked (and each state looked up once) before any tensor changes, so a
  // step is either wholly fused or wholly LibTorch's.
  std::vector<Slot> slots;
  last_step_fused_ = collect(slots);
  if (!last_step_fused_) {
    torch::optim::Adam::step();
    return loss;
  }
  for (Slot& slot : slots) {
    const torch::Tensor& p = slot.param;
    const torch::optim::AdamOptions& o = *slot.options;
    const double beta1 = std::get<0>(o.betas()), beta2 = std::get<1>(o.betas());
    if (slot.state == nullptr) {
      auto fresh = std::make_unique<torch::optim::AdamParamState>();
      fresh->step(0);
      fresh->exp_avg(torch::zeros_like(p, at::MemoryFormat::Contiguous));
      fresh->exp_avg_sq(torch::zeros_like(p, at::MemoryFormat::Contiguous));
      slot.state = fresh.get();
      state().emplace(std::move(slot.key), std::move(fresh));
    }
    auto& s = *slot.state;
    s.step(s.step() + 1);
    const double correction1 = 1 - std::pow(beta1, static_cast<double>(s.step()));
    const double correction2 = 1 - std::pow(beta2, static_cast<double>(s.step()));
    // The library's scalars, as its ops see them: each cast to float once.
    const AdamScalars k{static_cast<float>(beta1),
                        static_cast<float>(1 - beta1),
                        static_cast<float>(beta2),
                        static_cast<float>(1 - beta2),
                        static_cast<float>(std::sqrt(correction2)),
                        static_cast<float>(o.eps()),
                        static_cast<float>(-(o.lr() / correction1))};
    float* param = p.data_ptr<float>();
    const float* g = slot.grad.data_ptr<float>();
    float* m = s.exp_avg().data_ptr<float>();
    float* v = s.exp_avg_sq().data_ptr<float>();
    auto update = [&](int64_t begin, int64_t end) {
      adam_update(param + begin, g + begin, m + begin, v + begin, end - begin, k);
    };
    const int64_t n = p.numel();
    if (n < 2 * kGrain)
      update(0, n);
    else
      at::parallel_for(0, n, kGrain, update);
  }
  return loss;
}

}  // namespace bsms
