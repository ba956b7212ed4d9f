// Adam with the update of each parameter tensor done in one pass over its elements.
//
// torch::optim::Adam (LibTorch 1.13) runs about seven tensor ops per parameter tensor, two of
// them allocating (sqrt, division), plus two string-keyed state lookups; on the small graphs of
// the default scene that dispatch, not the arithmetic, is most of its cost (measured: 12 ms of a
// 104 ms BSMS step at latent 64 with 780K parameters in 264 tensors). FusedAdam computes the
// same update, in the same order of operations, in one loop per tensor: m ← β₁m + (1−β₁)g,
// v ← β₂v + (1−β₂)g², p ← p − (lr / (1−β₁ᵗ)) · m / (√v / √(1−β₂ᵗ) + ε).
//
// It *is* a torch::optim::Adam: the same options, the same per-parameter state (AdamParamState:
// step, exp_avg, exp_avg_sq) under the same keys, so checkpoints written by either read in the
// other. Options the fused loop does not cover (weight decay, AMSGrad, a parameter that is not
// a contiguous dense float tensor) make step() run the library's Adam for that step.
#pragma once

#include <torch/optim/adam.h>

#include <vector>

namespace bsms {

class FusedAdam : public torch::optim::Adam {
 public:
  FusedAdam(std::vector<torch::Tensor> params, torch::optim::AdamOptions defaults)
      : torch::optim::Adam(std::move(params), std::move(defaults)) {}

  torch::Tensor step(LossClosure closure = nullptr) override;

  // Whether the last step() took the fused loop (false: it ran torch::optim::Adam::step).
  bool last_step_fused() const { return last_step_fused_; }

 private:
  struct Slot;
  // Gathers the parameters with a gradient into `slots`; false where the fused loop does not
  // apply to one of them.
  bool collect(std::vector<Slot>& slots);
  bool last_step_fused_ = false;
};

}  // namespace bsms
