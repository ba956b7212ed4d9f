// An exponential moving average of a module's parameters, updated after every optimizer step.
//
// Late in training the iterates of Adam wander around a minimum: successive checkpoints of one run
// differ in rollout error by more than the training gains between them, and the mean of a few
// checkpoints' weights rolls out better than any of them (docs/results.md, "3-D: checkpoint
// selection by rollout"). The average follows the training weights with
//   e ← e + (1 − d)(p − e),   d = min(decay, (1 + n) / (10 + n)),
// n the updates before this one: early on d is small (the average forgets the random start within
// a few steps) and it reaches `decay` after about 10 / (1 − decay) steps, so that the average
// spans the last ~n/9 steps until then and ~1 / (1 − decay) steps after.
//
// Only floating-point parameters are averaged; buffers (normalizer statistics) are the module's.
#pragma once

#include <torch/nn/module.h>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace bsms {

class ParameterEma {
 public:
  // The average of `module`'s parameters (which it keeps referring to), started at their values.
  // `decay` in (0, 1).
  ParameterEma(const torch::nn::Module& module, double decay);

  // One update toward the module's parameters as they are now (after an optimizer step).
  void update();

  double decay() const { return decay_; }
  int64_t updates() const { return updates_; }
  // The decay the next update uses.
  double next_decay() const;

  // (dotted parameter name, average) in the module's parameter order.
  const std::vector<std::pair<std::string, torch::Tensor>>& averages() const { return averages_; }

  // Sets the state read from a checkpoint: `values` in averages() order, with their shapes.
  void restore(int64_t updates, const std::vector<torch::Tensor>& values);
  // Starts again from the module's parameters as they are now, with no update.
  void restart();
  // Exchanges the module's parameters with the average (twice: back as before, bit for bit), so
  // that the module predicts with the average meanwhile; see AverageInModule.
  void swap_with_module();

 private:
  double decay_;
  int64_t updates_ = 0;
  std::vector<torch::Tensor> params_;  // the module's, shared
  std::vector<std::pair<std::string, torch::Tensor>> averages_;
};

// Scope in which a module predicts with its parameters' average (validation during training);
// the training weights are back when it ends, also when it ends by an exception. No-op for null.
class AverageInModule {
 public:
  explicit AverageInModule(ParameterEma* ema) : ema_(ema) {
    if (ema_) ema_->swap_with_module();
  }
  ~AverageInModule() {
    if (ema_) ema_->swap_with_module();
  }
  AverageInModule(const AverageInModule&) = delete;
  AverageInModule& operator=(const AverageInModule&) = delete;

 private:
  ParameterEma* ema_;
};

}  // namespace bsms
