// The optimisation loop shared by `bsms train` and the experiments (heat sticks): Adam with the
// learning-rate schedule of train_config (warm-up, decay by the run's progress, which counts a
// time budget), a finite-loss check naming the step, a progress bar and per-step timing. What a
// step trains on and what happens after it (validation, checkpoints, logs) are the caller's.
#pragma once

#include <torch/optim/adam.h>
#include <torch/types.h>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "pipeline/runs/train_config.hpp"

namespace bsms {

struct FitOptions {
  OptimizerConfig optimizer;
  int64_t steps = 0;            // the schedule's length (and the last step)
  double time_budget_s = 0.0;   // > 0: stop once the run's wall time reaches it
  int64_t first_step = 0;       // resumed runs: the step to continue from ...
  double wall_before = 0.0;     // ... and the wall time already spent
  int64_t stop_step = 0;        // > 0: stop before the end (a checkpoint), at most `steps`
  std::string label = "train";  // progress bar and error messages
  bool quiet = false;           // no progress bar
};

struct FitStep {
  int64_t step = 0;     // steps done, this one included (1-based)
  double wall_s = 0.0;  // run wall time after it
  double loss = 0.0;
  double lr = 0.0;
  bool last = false;  // fit() stops after it (the last step, stop_step or the time budget spent)
};

struct FitHooks {
  // Loss of the batch of step `index` (0-based), with its graph: fit() runs backward and Adam.
  std::function<torch::Tensor(int64_t index)> loss;
  // Optional, after each step: validation, checkpoints, logs. Returns extra progress-bar text.
  std::function<std::string(const FitStep&)> after_step;
  // Optional, data-parallel training: called between backward and the optimizer step with this
  // process's loss and run wall time; averages the gradients over the ranks and returns the
  // loss over all of them and a wall time every rank agrees on. With it, the schedule and the
  // time budget follow that agreed time (the previous step's), so that all ranks take the same
  // learning rate and stop at the same step.
  struct Agreed {
    double loss = 0.0;
    double wall_s = 0.0;
  };
  std::function<Agreed(int64_t index, double loss, double wall_s)> synchronize;
};

struct FitResult {
  int64_t step = 0;  // steps done in all (resumed ones included)
  double wall_s = 0.0;
  double last_loss = 0.0;
  double last_lr = 0.0;
  std::vector<double> step_ms;  // this session's steps
  double median_step_ms() const;
};

// The schedule's progress of a run at `step` after `wall_s` seconds, 0..1: the larger of the
// step and time-budget shares, so that the learning rate ends where the run really ends.
double fit_progress(const FitOptions& options, int64_t step, double wall_s);

// Runs steps first_step .. stop (see FitOptions). A non-finite loss is a NumericalError naming
// the step and `options.label`.
FitResult fit(torch::optim::Adam& optimizer, const FitOptions& options, const FitHooks& hooks);

}  // namespace bsms
