#include "models/checkpoint.hpp"

#include <torch/serialize/input-archive.h>
#include <torch/serialize/output-archive.h>

#include <utility>
#include <vector>

#include "core/error.hpp"

namespace bsms {
namespace {

std::string first_line(const std::string& text) {
  return text.substr(0, text.find('\n'));
}

// Matches every entry of `module` against `archive`, collecting (target, value) pairs.
void collect(torch::nn::Module& module, torch::serialize::InputArchive& archive,
             const std::string& prefix, const std::string& path,
             std::vector<std::pair<torch::Tensor, torch::Tensor>>& pairs) {
  auto match = [&](const std::string& key, const torch::Tensor& target, bool is_buffer) {
    torch::Tensor value;
    bool found = false;
    try {
      found = archive.try_read(key, value, is_buffer);
    } catch (const c10::Error& e) {
      throw InputError(path + ": entry '" + prefix + key +
                       "' cannot be read: " + first_line(e.what_without_backtrace()));
    }
    if (!found) throw InputError(path + ": checkpoint has no entry '" + prefix + key + "'");
    if (value.sizes() != target.sizes() || value.scalar_type() != target.scalar_type()) {
      throw InputError(path + ": entry '" + prefix + key + "' has shape " +
                       std::string(c10::str(value.sizes())) + " " +
                       std::string(c10::toString(value.scalar_type())) + ", the model expects " +
                       std::string(c10::str(target.sizes())) + " " +
                       std::string(c10::toString(target.scalar_type())) +
                       " (checkpoint of a different model configuration?)");
    }
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
                       "' cannot be read: " + first_line(e.what_without_backtrace()));
    }
    if (!found)
      throw InputError(path + ": checkpoint has no module '" + prefix + child.key() + "'");
    collect(*child.value(), sub, prefix + child.key() + ".", path, pairs);
  }
}

}  // namespace

void save_module(const torch::nn::Module& module, const std::string& path) {
  try {
    torch::serialize::OutputArchive archive;
    module.save(archive);
    archive.save_to(path);
  } catch (const c10::Error& e) {
    throw IoError(path + ": cannot write checkpoint: " + first_line(e.what_without_backtrace()));
  }
}

void load_module(torch::nn::Module& module, const std::string& path) {
  torch::serialize::InputArchive archive;
  try {
    archive.load_from(path);
  } catch (const c10::Error& e) {
    throw InputError(path +
                     ": not a readable checkpoint: " + first_line(e.what_without_backtrace()));
  }
  read_module(module, archive, path);
}

void read_module(torch::nn::Module& module, torch::serialize::InputArchive& archive,
                 const std::string& path) {
  std::vector<std::pair<torch::Tensor, torch::Tensor>> pairs;
  collect(module, archive, "", path, pairs);
  torch::NoGradGuard no_grad;
  for (auto& [target, value] : pairs) target.copy_(value);
}

}  // namespace bsms
