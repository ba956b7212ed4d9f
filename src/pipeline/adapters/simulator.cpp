#include "pipeline/adapters/simulator.hpp"

#include <torch/torch.h>

#include <filesystem>

#include "core/error.hpp"
#include "models/graph_ops.hpp"
#include "pipeline/runs/run_files.hpp"

namespace bsms {

LearnedSimulator::LearnedSimulator(const ModelShape& shape, const ModelConfig& config, int levels) {
  GraphModelOptions o;
  o.input_size = shape.input_size;
  o.output_size = shape.output_size;
  o.latent = config.latent;
  o.position_dims = shape.position_dims;
  o.edge_set_fields = shape.edge_set_fields;
  o.edge_set_stretch = shape.edge_set_stretch;
  o.num_levels = levels;
  o.message_passing_steps = config.message_passing_steps;
  o.mp_per_level = config.mp_per_level;
  o.edge_normalizer = config.edge_normalizer == "on";
  bf16_ = config.precision == "bf16";
  if (config.type == "bsms") {
    o.mp_per_level_list = config.mp_per_level_list;
    model_ = std::make_shared<BsmsGnn>(o);
  } else {
    model_ = std::make_shared<MeshGraphNets>(o);
  }
  register_module("model", model_);
  input_norm_ = register_module("input_normalizer", std::make_shared<Normalizer>(shape.input_size));
  output_norm_ =
      register_module("output_normalizer", std::make_shared<Normalizer>(shape.output_size));
}

int64_t LearnedSimulator::num_parameters() const {
  int64_t total = 0;
  for (const auto& p : parameters()) total += p.numel();
  return total;
}

torch::Tensor LearnedSimulator::forward_normalized(const Batch& batch) {
  // The products' precision for this model's forward (and, saved by the kernels, its backward);
  // restored after, so that models of different precision can run in one process.
  const MatmulPrecision before = matmul_precision();
  set_matmul_precision(bf16_ ? MatmulPrecision::kBFloat16 : MatmulPrecision::kFloat32);
  struct Restore {
    MatmulPrecision p;
    ~Restore() { set_matmul_precision(p); }
  } restore{before};
  return model_->forward(input_norm_->normalize(batch.inputs), batch.positions, batch.graph);
}

torch::Tensor LearnedSimulator::loss(const Batch& batch, const torch::Tensor& target,
                                     double rigid_weight) {
  auto prediction = forward_normalized(batch);
  auto goal = target;
  if (batch.project) {
    // Compare what the physics allows (Lagrangian: the momentum-conserving parts; the group-wide
    // part of the training noise is not the model's to undo).
    prediction = output_norm_->normalize(batch.project(batch, output_norm_->inverse(prediction)));
    goal = batch.project(batch, target);
  }
  const auto diff = prediction - output_norm_->normalize(goal);
  auto error = diff.pow(2).sum(1);
  if (rigid_weight > 0 && batch.rigid_part) {
    // The rigid part of the raw error, measured in the normalised units of the loss.
    const int64_t d = batch.cur.size(1);  // the motion channels (not a stress output)
    const auto scale = output_norm_->std().to(diff.dtype()).narrow(0, 0, d);
    const auto rigid = batch.rigid_part(batch, diff.narrow(1, 0, d) * scale) / scale;
    error = error + rigid_weight * rigid.pow(2).sum(1);
  }
  return error.index({batch.mask}).mean();
}

void LearnedSimulator::accumulate_statistics(const Batch& batch, const torch::Tensor& target,
                                             bool all_nodes) {
  torch::NoGradGuard no_grad;
  input_norm_->accumulate(batch.inputs);
  output_norm_->accumulate(all_nodes ? target : target.index({batch.mask}));
  model_->accumulate_edge_statistics(batch.positions, batch.graph);
}

std::vector<torch::Tensor> LearnedSimulator::normalizer_sums() {
  auto sums = input_norm_->sums();
  for (auto& t : output_norm_->sums()) sums.push_back(t);
  for (auto& t : model_->edge_normalizer_sums()) sums.push_back(t);
  return sums;
}

torch::Tensor LearnedSimulator::zero_prediction_loss(const Batch& batch,
                                                     const torch::Tensor& target) const {
  torch::NoGradGuard no_grad;
  const auto error =
      (output_norm_->normalize(torch::zeros_like(target)) - output_norm_->normalize(target))
          .pow(2)
          .sum(1);
  return error.index({batch.mask}).mean();
}

torch::Tensor LearnedSimulator::predict(const Batch& batch) {
  const auto out = output_norm_->inverse(forward_normalized(batch));
  return batch.project ? batch.project(batch, out) : out;
}

void save_checkpoint(const std::string& path, LearnedSimulator& simulator,
                     torch::optim::Adam& optimizer, const CheckpointInfo& info,
                     const ParameterEma* ema) {
  save_checkpoint_file(path, simulator, &optimizer, &info, ema);
}

CheckpointInfo load_checkpoint(const std::string& path, LearnedSimulator& simulator,
                               torch::optim::Adam* optimizer, ParameterEma* ema) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    const std::string legacy = legacy_checkpoint_path(path);
    if (!legacy.empty() && std::filesystem::exists(legacy, ec))
      throw InputError(legacy_checkpoint_message(legacy));
  }
  return load_checkpoint_bytes(read_checkpoint_bytes(path), path, simulator, optimizer, ema);
}

CheckpointInfo load_checkpoint_bytes(const std::string& bytes, const std::string& name,
                                     LearnedSimulator& simulator, torch::optim::Adam* optimizer,
                                     ParameterEma* ema) {
  return load_checkpoint_image(name, bytes, simulator, optimizer, /*require_training=*/true, ema);
}

}  // namespace bsms
