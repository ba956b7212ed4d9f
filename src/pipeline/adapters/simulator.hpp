// The learned simulator: a graph model plus its input and output normalizers, saved together.
#pragma once

#include <torch/nn/module.h>
#include <torch/optim/adam.h>

#include <cmath>
#include <memory>
#include <string>

#include "models/checkpoint.hpp"
#include "models/layers.hpp"
#include "models/networks.hpp"
#include "pipeline/adapters/adapter.hpp"
#include "pipeline/runs/train_config.hpp"

namespace bsms {

class LearnedSimulator : public torch::nn::Module {
 public:
  // `levels`: the level count of every graph the BSMS model sees (1 for MeshGraphNets).
  LearnedSimulator(const ModelShape& shape, const ModelConfig& model, int levels);

  // Mean over predicted nodes of the squared error in normalised target space. `target` is the
  // raw acceleration [N, dim]; the normalizers are settled beforehand (accumulate_statistics).
  // With the batch's projection (Batch::project) both sides are projected first. With
  // `rigid_weight` w > 0 the rigid part of each body's error (Batch::rigid_part, taken in raw
  // units and normalised back) counts 1 + w times.
  torch::Tensor loss(const Batch& batch, const torch::Tensor& target, double rigid_weight = 0.0);
  // Adds the batch's inputs and targets (of the predicted nodes, or with `all_nodes` of every
  // node, as MeshGraphNets' reference) and the model's edge features to the normalizer
  // statistics.
  void accumulate_statistics(const Batch& batch, const torch::Tensor& target,
                             bool all_nodes = false);
  // The loss of predicting zero acceleration, in the same normalised units as loss(): the
  // reference a model must beat (no gradient).
  torch::Tensor zero_prediction_loss(const Batch& batch, const torch::Tensor& target) const;
  // Raw output predicted for the batch [N, output_size], through the batch's projection.
  torch::Tensor predict(const Batch& batch);

  // Both normalizers' sums (Normalizer::sums), to be added up over data-parallel ranks.
  std::vector<torch::Tensor> normalizer_sums();

  GraphModel& model() { return *model_; }
  int64_t num_parameters() const;

 private:
  torch::Tensor forward_normalized(const Batch& batch);
  std::shared_ptr<GraphModel> model_;
  std::shared_ptr<Normalizer> input_norm_, output_norm_;
  bool bf16_ = false;  // model.precision "bf16": bfloat16 matrix products (models/graph_ops.hpp)
};

// Checkpoint (models/checkpoint.hpp, HDF5): simulator parameters and buffers, optimizer state
// and the training step, written atomically. Loading validates the whole file before anything is
// copied; errors (missing, damaged, mismatched, non-finite) are InputErrors naming the file and
// the entry. A run that has only a LibTorch checkpoint (latest.pt, older bsms) is refused with a
// line saying how to convert it (`bsms convert-checkpoint`).
using CheckpointInfo = TrainingState;
void save_checkpoint(const std::string& path, LearnedSimulator& simulator,
                     torch::optim::Adam& optimizer, const CheckpointInfo& info,
                     const ParameterEma* ema = nullptr);
CheckpointInfo load_checkpoint(const std::string& path, LearnedSimulator& simulator,
                               torch::optim::Adam* optimizer, ParameterEma* ema = nullptr);
// The same from a checkpoint file's bytes (data-parallel ranks get rank 0's); `name` for errors.
CheckpointInfo load_checkpoint_bytes(const std::string& bytes, const std::string& name,
                                     LearnedSimulator& simulator, torch::optim::Adam* optimizer,
                                     ParameterEma* ema = nullptr);

}  // namespace bsms
