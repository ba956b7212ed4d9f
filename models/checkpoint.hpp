// Checkpoints as HDF5 files that bsms reads itself (docs/formats.md "Checkpoints"): a module's
// parameters and buffers, and for training checkpoints the Adam state, the step, the wall time,
// the losses and, when training keeps one, the moving average of the parameters (ParameterEma).
// Reading validates the whole file before anything is copied: every entry present and no other,
// dtype and shape equal to the module's, storage sizes consistent, values finite, optimizer state
// matching the parameters. Every failure is an InputError naming the file and the entry.
// (LibTorch's archives are not read here: loading one runs code from it.)
#pragma once

#include <torch/nn/module.h>
#include <torch/optim/adam.h>

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "models/checkpoint_format.hpp"
#include "models/parameter_ema.hpp"

namespace bsms {

constexpr int64_t kCheckpointVersion = 1;

// What a training checkpoint holds besides tensors. The losses are NaN when not measured.
struct TrainingState {
  int64_t step = 0;
  double wall_s = 0.0;
  double loss = std::nan("");
  double valid_loss = std::nan("");
  double valid_zero_prediction = std::nan("");
};

// Writes `module` (and, for a training checkpoint, `optimizer` and `state`; both or neither; and
// `ema`, the average of the module's parameters, when training keeps one) to `path` atomically (a
// temporary file renamed into place). IoError naming the file on failure.
void save_checkpoint_file(const std::string& path, const torch::nn::Module& module,
                          const torch::optim::Adam* optimizer, const TrainingState* state,
                          const ParameterEma* ema = nullptr);

// Reads a checkpoint file's bytes (`name` names it in errors) into `module` and, when given,
// `optimizer` (which must then be a training checkpoint whose optimizer covers the module's
// parameters as `optimizer` does). With `require_training` (implied by an optimizer) a module
// checkpoint is refused. Nothing is changed unless the whole file checks. Returns the training
// state (a module checkpoint: step 0, losses NaN).
// A checkpoint with an average of the parameters: without an optimizer (to predict with) the
// module gets the average, which is the checkpoint's model; with one (to train on) the module gets
// the training weights and `ema`, when given, the average (or, where the file has none, a fresh
// start from the loaded weights).
TrainingState load_checkpoint_image(const std::string& name, const std::string& bytes,
                                    torch::nn::Module& module, torch::optim::Adam* optimizer,
                                    bool require_training = false, ParameterEma* ema = nullptr);

// The whole file read into memory (a regular file; InputError naming it when missing or
// unreadable).
std::string read_checkpoint_bytes(const std::string& path);

// Writes every parameter and buffer of `module` to `path` (a module checkpoint).
void save_module(const torch::nn::Module& module, const std::string& path);
// Reads a module or training checkpoint's module part into `module` (same checks as above).
void load_module(torch::nn::Module& module, const std::string& path);

// A checkpoint checked on its own, without a module to compare with (bsms info, checkpoint_diff):
// format, version, types, storage, finite values, optimizer state against the entries it names.
struct CheckpointTensor {
  std::string name;  // the dotted entry name
  torch::Tensor value;
};
struct AdamSlot {         // Adam's state of one parameter
  int64_t index = 0;      // the parameter's position in param_groups order
  std::string parameter;  // its dotted name
  int64_t step = 0;
  torch::Tensor exp_avg, exp_avg_sq, max_exp_avg_sq;  // the last one with amsgrad only
};
struct AdamGroup {
  double lr = 0, beta1 = 0, beta2 = 0, eps = 0, weight_decay = 0;
  bool amsgrad = false;
  int64_t size = 0;  // parameters in the group
};
struct CheckpointContents {
  bool training = false;
  TrainingState state;
  std::vector<CheckpointTensor> model;  // read: sorted by name
  std::vector<AdamGroup> groups;
  std::vector<AdamSlot> slots;  // by index
  // A training checkpoint's average of the parameters (empty: none): by parameter name (read:
  // sorted), its decay and the updates it has had.
  std::vector<CheckpointTensor> ema;
  double ema_decay = 0.0;
  int64_t ema_updates = 0;
};
CheckpointContents read_checkpoint_contents(const std::string& name, const std::string& bytes);

// What save_checkpoint_file writes (the tensors are shared, not copied), and the writer itself:
// any contents, unchecked, so that tests and fuzzing can write damaged checkpoints.
CheckpointContents checkpoint_contents(const torch::nn::Module& module,
                                       const torch::optim::Adam* optimizer,
                                       const TrainingState* state,
                                       const ParameterEma* ema = nullptr);
void write_checkpoint_contents(const std::string& path, const CheckpointContents& contents);

}  // namespace bsms
