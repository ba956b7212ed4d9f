// Saving and loading module parameters and buffers (torch::serialize archives) with clear errors.
#pragma once

#include <torch/nn/module.h>
#include <torch/serialize/input-archive.h>

#include <string>

namespace bsms {

// Writes every parameter and buffer of `module` to `path`. IoError naming the file on failure.
void save_module(const torch::nn::Module& module, const std::string& path);

// Reads parameters and buffers saved by save_module into `module`, which must have the same
// structure: InputError naming the file and the entry on a missing entry or a shape mismatch, or
// when the file is not a readable archive. Nothing is changed unless every entry matches.
void load_module(torch::nn::Module& module, const std::string& path);

// The same check-then-copy from an archive already loaded (e.g. a training checkpoint holding the
// module next to optimizer state); `path` names the file in errors.
void read_module(torch::nn::Module& module, torch::serialize::InputArchive& archive,
                 const std::string& path);

}  // namespace bsms
