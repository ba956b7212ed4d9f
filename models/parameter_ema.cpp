#include "models/parameter_ema.hpp"

#include <ATen/Parallel.h>
#include <torch/torch.h>

#include <algorithm>
#include <stdexcept>

namespace bsms {
namespace {

// Elements per task of the parallel loop (as the fused Adam's).
constexpr int64_t kGrain = 16384;

void move_toward(float* __restrict e, const float* __restrict p, int64_t n, float rate) {
  for (int64_t i = 0; i < n; ++i) e[i] += rate * (p[i] - e[i]);
}

}  // namespace

ParameterEma::ParameterEma(const torch::nn::Module& module, double decay) : decay_(decay) {
  if (!(decay > 0.0 && decay < 1.0))
    throw std::invalid_argument("ParameterEma: decay must be in (0, 1)");
  torch::NoGradGuard no_grad;
  for (const auto& p : module.named_parameters(/*recurse=*/true)) {
    if (!p.value().is_floating_point()) continue;
    params_.push_back(p.value());
    averages_.emplace_back(p.key(), p.value().detach().clone().contiguous());
  }
}

double ParameterEma::next_decay() const {
  const double n = static_cast<double>(updates_);
  return std::min(decay_, (1.0 + n) / (10.0 + n));
}

void ParameterEma::update() {
  const double d = next_decay();
  torch::NoGradGuard no_grad;
  for (size_t i = 0; i < params_.size(); ++i) {
    const torch::Tensor& p = params_[i];
    torch::Tensor& e = averages_[i].second;
    if (p.scalar_type() == torch::kFloat && p.is_contiguous() && p.device().is_cpu()) {
      float* ep = e.data_ptr<float>();
      const float* pp = p.data_ptr<float>();
      const auto rate = static_cast<float>(1.0 - d);
      at::parallel_for(0, p.numel(), kGrain, [&](int64_t begin, int64_t end) {
        move_toward(ep + begin, pp + begin, end - begin, rate);
      });
    } else {
      e.lerp_(p.detach().to(e.scalar_type()), 1.0 - d);
    }
  }
  ++updates_;
}

void ParameterEma::restore(int64_t updates, const std::vector<torch::Tensor>& values) {
  if (updates < 0 || values.size() != averages_.size())
    throw std::invalid_argument("ParameterEma::restore: state does not match the module");
  for (size_t i = 0; i < values.size(); ++i)
    if (values[i].sizes() != averages_[i].second.sizes() ||
        values[i].scalar_type() != averages_[i].second.scalar_type())
      throw std::invalid_argument("ParameterEma::restore: " + averages_[i].first +
                                  " has another shape");
  torch::NoGradGuard no_grad;
  for (size_t i = 0; i < values.size(); ++i) averages_[i].second.copy_(values[i]);
  updates_ = updates;
}

void ParameterEma::restart() {
  torch::NoGradGuard no_grad;
  for (size_t i = 0; i < params_.size(); ++i) averages_[i].second.copy_(params_[i]);
  updates_ = 0;
}

void ParameterEma::swap_with_module() {
  torch::NoGradGuard no_grad;
  for (size_t i = 0; i < params_.size(); ++i) {
    const torch::Tensor weights = params_[i].detach().clone();
    params_[i].detach().copy_(averages_[i].second);
    averages_[i].second.copy_(weights);
  }
}

}  // namespace bsms
