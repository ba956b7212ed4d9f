#include "pipeline/train/legacy_checkpoint.hpp"

#include <torch/serialize/input-archive.h>
#include <torch/torch.h>

#include <filesystem>
#include <utility>
#include <vector>

#include "core/error.hpp"
#include "models/fused_adam.hpp"
#include "pipeline/adapters/run_adapter.hpp"
#include "pipeline/adapters/simulator.hpp"
#include "pipeline/runs/run_files.hpp"
#include "pipeline/train/trainer.hpp"

namespace bsms {
namespace legacy {

std::string archive_error_line(const c10::Error& e) {
  const std::string what = e.what_without_backtrace();
  return what.substr(0, what.find('\n'));
}

// The module part of an archive written by torch::nn::Module::save, matched entry by entry
// against `module` (collecting (target, value) pairs; nothing is copied here).
void collect_module(torch::nn::Module& module, torch::serialize::InputArchive& archive,
                    const std::string& prefix, const std::string& path,
                    std::vector<std::pair<torch::Tensor, torch::Tensor>>& pairs) {
  auto match = [&](const std::string& key, const torch::Tensor& target, bool is_buffer) {
    torch::Tensor value;
    bool found = false;
    try {
      found = archive.try_read(key, value, is_buffer);
    } catch (const c10::Error& e) {
      throw InputError(path + ": entry '" + prefix + key +
                       "' cannot be read: " + archive_error_line(e));
    }
    if (!found) throw InputError(path + ": checkpoint has no entry '" + prefix + key + "'");
    if (value.sizes() != target.sizes() || value.scalar_type() != target.scalar_type())
      throw InputError(path + ": entry '" + prefix + key +
                       "' does not fit the run's model (checkpoint of another configuration?)");
    pairs.emplace_back(target, value);
  };
  for (const auto& p : module.named_parameters(/*recurse=*/false)) match(p.key(), p.value(), false);
  for (const auto& b : module.named_buffers(/*recurse=*/false)) match(b.key(), b.value(), true);
  for (const auto& child : module.named_children()) {
    torch::serialize::InputArchive sub;
    bool found = false;
    try {
      found = archive.try_read(child.key(), sub);
    } catch (const c10::Error& e) {
      throw InputError(path + ": module '" + prefix + child.key() +
                       "' cannot be read: " + archive_error_line(e));
    }
    if (!found)
      throw InputError(path + ": checkpoint has no module '" + prefix + child.key() + "'");
    collect_module(*child.value(), sub, prefix + child.key() + ".", path, pairs);
  }
}

}  // namespace legacy

ConvertedCheckpoint convert_torch_checkpoint(const std::string& run) {
  namespace fs = std::filesystem;
  ConvertedCheckpoint done;
  done.to = run_checkpoint_path(run);
  done.from = legacy_checkpoint_path(done.to);
  if (!fs::is_regular_file(done.from))
    throw InputError(done.from + ": not found (nothing to convert)");
  if (fs::exists(done.to))
    throw InputError(done.to +
                     ": already exists (the run was converted or trained by this "
                     "bsms); nothing to convert");
  const RunFolder folder = RunFolder::open(run);
  const Json& features = folder.features_resolved;
  const ModelShape shape = adapter_from_features(features, folder.config_path)->model_shape();
  LearnedSimulator simulator(shape, folder.config.model, folder.levels);
  FusedAdam optimizer(simulator.parameters(),
                      torch::optim::AdamOptions(folder.config.optimizer.lr));

  CheckpointInfo info;
  try {
    torch::serialize::InputArchive archive;
    archive.load_from(done.from);
    std::vector<std::pair<torch::Tensor, torch::Tensor>> pairs;
    legacy::collect_module(simulator, archive, "", done.from, pairs);
    {
      torch::NoGradGuard no_grad;
      for (auto& [target, value] : pairs) target.copy_(value);
    }
    torch::serialize::InputArchive optimizer_archive;
    archive.read("optimizer", optimizer_archive);
    optimizer.load(optimizer_archive);
    torch::Tensor step, wall, losses;
    archive.read("step", step);
    archive.read("wall_s", wall);
    info.step = step.item<int64_t>();
    info.wall_s = wall.item<double>();
    if (archive.try_read("losses", losses) && losses.numel() == 3) {
      info.loss = losses[0].item<double>();
      info.valid_loss = losses[1].item<double>();
      info.valid_zero_prediction = losses[2].item<double>();
    }
  } catch (const c10::Error& e) {
    throw InputError(done.from + ": not a readable bsms LibTorch checkpoint (" +
                     legacy::archive_error_line(e) + ")");
  }
  save_checkpoint(done.to, simulator, optimizer, info);
  // Read back through the validating loader (NaN values, damaged state): a file that does not
  // load is removed again, leaving the run as it was.
  try {
    LearnedSimulator check(shape, folder.config.model, folder.levels);
    FusedAdam check_optimizer(check.parameters(),
                              torch::optim::AdamOptions(folder.config.optimizer.lr));
    load_checkpoint(done.to, check, &check_optimizer);
  } catch (...) {
    std::error_code ec;
    fs::remove(done.to, ec);
    throw;
  }
  done.step = info.step;
  return done;
}

}  // namespace bsms
