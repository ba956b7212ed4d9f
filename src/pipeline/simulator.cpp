#include "pipeline/simulator.hpp"

#include <torch/torch.h>

#include <filesystem>
#include <sstream>

#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "models/checkpoint.hpp"

namespace bsms {

ModelShape model_shape(const LagrangianSpec& spec) {
  ModelShape s;
  s.input_size = spec.input_size();
  s.output_size = spec.output_size();
  s.position_dims = {spec.mesh_dimension(), spec.dim};       // mesh X, world x
  s.edge_set_fields = {{0, 1}};                              // mesh edges: both offsets
  if (spec.has_contact()) s.edge_set_fields.push_back({1});  // contact edges: world offsets
  if (spec.strain_scale > 0) s.edge_set_stretch = {EdgeStretch{0, 1, 1.0 / spec.strain_scale}};
  return s;
}

ModelShape model_shape(const EulerianSpec& spec) {
  ModelShape s;
  s.input_size = spec.input_size();
  s.output_size = spec.output_size();
  s.position_dims = {spec.dim};
  s.edge_set_fields = {{0}};
  return s;
}

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
  if (config.type == "bsms") {
    o.level_blocks = config.level_blocks;
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
  return model_->forward(input_norm_->normalize(batch.inputs), batch.positions, batch.graph);
}

torch::Tensor LearnedSimulator::loss(const Batch& batch, const torch::Tensor& target,
                                     double rigid_weight) {
  auto prediction = forward_normalized(batch);
  auto goal = target;
  if (batch.num_groups > 0) {
    // Free groups: compare the momentum-conserving parts (the group-wide part of the training
    // noise is not the model's to undo).
    prediction =
        output_norm_->normalize(project_momentum(batch, output_norm_->inverse(prediction)));
    goal = project_momentum(batch, target);
  }
  const auto diff = prediction - output_norm_->normalize(goal);
  auto error = diff.pow(2).sum(1);
  if (rigid_weight > 0) {
    // The rigid part of the raw error, measured in the normalised units of the loss.
    const auto scale = output_norm_->std().to(diff.dtype());
    const auto rigid = rigid_part(batch, diff * scale) / scale;
    error = error + rigid_weight * rigid.pow(2).sum(1);
  }
  return error.index({batch.mask}).mean();
}

void LearnedSimulator::accumulate_statistics(const Batch& batch, const torch::Tensor& target) {
  torch::NoGradGuard no_grad;
  input_norm_->accumulate(batch.inputs);
  output_norm_->accumulate(target.index({batch.mask}));
}

std::vector<torch::Tensor> LearnedSimulator::normalizer_sums() {
  auto sums = input_norm_->sums();
  for (auto& t : output_norm_->sums()) sums.push_back(t);
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
  return project_momentum(batch, output_norm_->inverse(forward_normalized(batch)));
}

void save_checkpoint(const std::string& path, LearnedSimulator& simulator,
                     torch::optim::Optimizer& optimizer, const CheckpointInfo& info) {
  AtomicOutput out(path);
  try {
    torch::serialize::OutputArchive archive;
    simulator.save(archive);
    torch::serialize::OutputArchive optimizer_archive;
    optimizer.save(optimizer_archive);
    archive.write("optimizer", optimizer_archive);
    archive.write("step", torch::tensor({info.step}, torch::kInt64));
    archive.write("wall_s", torch::tensor({info.wall_s}, torch::kFloat64));
    archive.write("losses", torch::tensor({info.loss, info.valid_loss, info.valid_baseline},
                                          torch::kFloat64));
    archive.save_to(out.temp_path());
  } catch (const c10::Error& e) {
    throw IoError(path + ": cannot write checkpoint (" + std::string(e.what_without_backtrace()) +
                  ")");
  }
  out.commit();
}

namespace {

CheckpointInfo read_checkpoint(torch::serialize::InputArchive& archive, const std::string& path,
                               LearnedSimulator& simulator, torch::optim::Optimizer* optimizer) {
  CheckpointInfo info;
  read_module(simulator, archive, path);  // checks every entry's shape before copying
  try {
    if (optimizer) {
      torch::serialize::InputArchive optimizer_archive;
      archive.read("optimizer", optimizer_archive);
      optimizer->load(optimizer_archive);
    }
    torch::Tensor step, wall;
    archive.read("step", step);
    archive.read("wall_s", wall);
    info.step = step.item<int64_t>();
    info.wall_s = wall.item<double>();
    torch::Tensor losses;
    if (archive.try_read("losses", losses) && losses.numel() == 3) {
      info.loss = losses[0].item<double>();
      info.valid_loss = losses[1].item<double>();
      info.valid_baseline = losses[2].item<double>();
    }
  } catch (const c10::Error& e) {
    std::string what = e.what_without_backtrace();
    throw InputError(path + ": checkpoint lacks training state (" +
                     what.substr(0, what.find('\n')) + ")");
  }
  return info;
}

}  // namespace

CheckpointInfo load_checkpoint(const std::string& path, LearnedSimulator& simulator,
                               torch::optim::Optimizer* optimizer) {
  if (!std::filesystem::exists(path)) throw InputError(path + ": checkpoint not found");
  torch::serialize::InputArchive archive;
  try {
    archive.load_from(path);
  } catch (const c10::Error&) {
    throw InputError(path + ": not a readable checkpoint (truncated or corrupt)");
  }
  return read_checkpoint(archive, path, simulator, optimizer);
}

CheckpointInfo load_checkpoint_bytes(const std::string& bytes, const std::string& name,
                                     LearnedSimulator& simulator,
                                     torch::optim::Optimizer* optimizer) {
  torch::serialize::InputArchive archive;
  try {
    std::istringstream in(bytes);
    archive.load_from(in);
  } catch (const c10::Error&) {
    throw InputError(name + ": not a readable checkpoint (truncated or corrupt)");
  }
  return read_checkpoint(archive, name, simulator, optimizer);
}

}  // namespace bsms
