// libFuzzer target for the checkpoint loader (models/checkpoint.cpp): the one path by which
// rollout, bsms info and train --resume read RUN/checkpoints/latest.h5 (and data-parallel ranks
// rank 0's bytes). The input is a mode byte, then
//   even mode: an HDF5 file image, loaded as is (seeds: real checkpoints of a small model; the
//              fuzzer's byte flips, truncations and splices damage them);
//   odd mode:  a program of 3-byte operations applied to the contents of a real checkpoint
//              (entries dropped, reshaped, retyped, renamed or added; NaN, inf and negative
//              values; optimizer states moved, renamed, dropped; group options, steps and times
//              out of range), written as a well-formed file and loaded.
// Each file is loaded into a small module (two Linear layers and a Normalizer) and its Adam
// optimizer. InputError is the only allowed failure, and after it nothing in the module or the
// optimizer has changed; a load that succeeds gives finite values and states shaped like their
// parameters. BSMS_FUZZ_WRITE_SEEDS=DIR fuzz_checkpoint writes the seeds to DIR.
#include <torch/torch.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "h5_builder.hpp"
#include "models/checkpoint.hpp"
#include "models/fused_adam.hpp"
#include "models/layers.hpp"
#include "seeds.hpp"

namespace {

struct Small : torch::nn::Module {
  Small() {
    first = register_module("first", torch::nn::Linear(3, 4));
    second = register_module("second", torch::nn::Linear(4, 2));
    norm = register_module("norm", std::make_shared<bsms::Normalizer>(3));
  }
  torch::nn::Linear first{nullptr}, second{nullptr};
  std::shared_ptr<bsms::Normalizer> norm;
};

struct Trained {
  std::shared_ptr<Small> model;
  std::unique_ptr<bsms::FusedAdam> optimizer;
};

// A module after `steps` Adam steps (the second layer's bias gets no gradient: no state).
Trained trained(int steps, bool amsgrad) {
  torch::manual_seed(3);
  Trained t;
  t.model = std::make_shared<Small>();
  std::vector<torch::Tensor> params = t.model->parameters();
  t.optimizer =
      std::make_unique<bsms::FusedAdam>(params, torch::optim::AdamOptions(1e-3).amsgrad(amsgrad));
  const torch::Tensor x = torch::randn({5, 3});
  t.model->norm->accumulate(x);
  for (int i = 0; i < steps; ++i) {
    t.optimizer->zero_grad();
    const torch::Tensor y = t.model->second->forward(torch::tanh(t.model->first->forward(x)));
    y.pow(2).sum().backward();
    t.model->second->bias.mutable_grad() = torch::Tensor();
    t.optimizer->step();
  }
  return t;
}

std::string image_of(const torch::nn::Module& m, const torch::optim::Adam* o, int64_t step) {
  const std::string path = bsms_fuzz::scratch_dir("checkpoint") + "/seed.h5";
  const bsms::TrainingState state{step, 1.5, 0.25, 0.5, 0.75};
  bsms::save_checkpoint_file(path, m, o, o ? &state : nullptr);
  return bsms::read_checkpoint_bytes(path);
}

const std::string& valid_image() {
  static const std::string image = [] {
    Trained t = trained(2, false);
    return image_of(*t.model, t.optimizer.get(), 2);
  }();
  return image;
}

std::vector<std::vector<uint8_t>> seeds() {
  std::vector<std::vector<uint8_t>> out;
  auto add = [&](uint8_t mode, const std::string& bytes) {
    std::vector<uint8_t> s{mode};
    s.insert(s.end(), bytes.begin(), bytes.end());
    out.push_back(s);
  };
  add(0, valid_image());
  Trained ams = trained(3, true);
  add(2, image_of(*ams.model, ams.optimizer.get(), 3));
  add(4, image_of(*ams.model, nullptr, 0));
  Trained fresh = trained(0, false);
  add(6, image_of(*fresh.model, fresh.optimizer.get(), 0));
  // Structure programs: each operation once, then a few pairs.
  std::vector<uint8_t> all{1};
  for (uint8_t op = 0; op < 18; ++op) {
    out.push_back({1, op, 1, 2});
    all.insert(all.end(), {op, static_cast<uint8_t>(op * 7), static_cast<uint8_t>(op * 13)});
  }
  out.push_back(all);
  return out;
}

// Everything a load could change, cloned.
std::vector<torch::Tensor> snapshot(const torch::nn::Module& m, const torch::optim::Adam& o) {
  std::vector<torch::Tensor> out;
  for (const auto& t : m.parameters()) out.push_back(t.detach().clone());
  for (const auto& t : m.buffers()) out.push_back(t.clone());
  for (const auto& group : o.param_groups()) {
    const auto& opt = static_cast<const torch::optim::AdamOptions&>(group.options());
    out.push_back(torch::tensor({opt.lr(), std::get<0>(opt.betas()), std::get<1>(opt.betas()),
                                 opt.eps(), opt.weight_decay(), double(opt.amsgrad())},
                                torch::kFloat64));
    for (const auto& p : group.params()) {
      const auto it = o.state().find(c10::guts::to_string(p.unsafeGetTensorImpl()));
      if (it == o.state().end()) {
        out.push_back(torch::zeros({0}));
        continue;
      }
      const auto& s = static_cast<const torch::optim::AdamParamState&>(*it->second);
      out.push_back(torch::tensor({s.step()}, torch::kInt64));
      out.push_back(s.exp_avg().clone());
      out.push_back(s.exp_avg_sq().clone());
    }
  }
  return out;
}

bool same(const std::vector<torch::Tensor>& a, const std::vector<torch::Tensor>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (a[i].sizes() != b[i].sizes() || a[i].scalar_type() != b[i].scalar_type() ||
        !torch::equal(a[i], b[i]))
      return false;
  return true;
}

// Loads `bytes` into the target module and optimizer and checks the promises.
void load(const std::string& bytes) {
  static Trained target = trained(1, false);
  const std::vector<torch::Tensor> before = snapshot(*target.model, *target.optimizer);
  try {
    bsms::load_checkpoint_image("fuzz.h5", bytes, *target.model, target.optimizer.get());
  } catch (const bsms::InputError& e) {
    bsms_fuzz::refused(e);
    if (!same(before, snapshot(*target.model, *target.optimizer))) {
      std::fprintf(stderr, "refused (%s), but the module or optimizer changed\n", e.what());
      std::abort();
    }
    return;
  }
  for (const auto& t : target.model->parameters())
    if (!torch::isfinite(t).all().item<bool>()) std::abort();
  for (const auto& p : target.model->parameters()) {
    const auto it = target.optimizer->state().find(c10::guts::to_string(p.unsafeGetTensorImpl()));
    if (it == target.optimizer->state().end()) continue;
    const auto& s = static_cast<const torch::optim::AdamParamState&>(*it->second);
    if (s.exp_avg().sizes() != p.sizes() || s.exp_avg_sq().sizes() != p.sizes()) std::abort();
  }
  bsms::read_checkpoint_contents("fuzz.h5", bytes);  // what loads, bsms info reads too
}

double odd_value(uint8_t b) {
  switch (b % 6) {
    case 0:
      return std::nan("");
    case 1:
      return INFINITY;
    case 2:
      return -INFINITY;
    case 3:
      return -1.0;
    case 4:
      return 1e300;
    default:
      return b;
  }
}

// Element i of a contiguous floating tensor (through its data: LibTorch's scalar fill refuses
// some values for float32).
void set_value(torch::Tensor& t, int64_t i, double v) {
  if (t.scalar_type() == torch::kFloat)
    t.data_ptr<float>()[i] = static_cast<float>(v);
  else if (t.scalar_type() == torch::kDouble)
    t.data_ptr<double>()[i] = v;
}

torch::ScalarType odd_type(uint8_t b) {
  const torch::ScalarType types[] = {torch::kFloat, torch::kDouble, torch::kLong, torch::kInt,
                                     torch::kByte};
  return types[b % 5];
}

// Applies the program to the valid checkpoint's contents.
void mutate(bsms::CheckpointContents& c, const uint8_t* p, size_t n) {
  for (size_t i = 0; i + 3 <= n; i += 3) {
    const uint8_t op = p[i] % 18, a = p[i + 1], b = p[i + 2];
    auto& model = c.model;
    auto& slots = c.slots;
    switch (op) {
      case 0:
        if (!model.empty()) model.erase(model.begin() + a % model.size());
        break;
      case 1:
        if (!model.empty()) {
          torch::Tensor& t = model[a % model.size()].value;
          std::vector<int64_t> shape(b % 3 + 1, 1);
          shape[0] = b % 7;
          t = torch::zeros(shape, t.options());
        }
        break;
      case 2:
        if (!model.empty()) {
          torch::Tensor& t = model[a % model.size()].value;
          if (t.numel() > 0) set_value(t, b % t.numel(), odd_value(b));
        }
        break;
      case 3:
        if (!model.empty()) {
          torch::Tensor& t = model[a % model.size()].value;
          t = t.to(odd_type(b));
        }
        break;
      case 4:
        if (!model.empty()) {
          std::string& name = model[a % model.size()].name;
          if (b % 2)
            name = model[b % model.size()].name;
          else
            name += static_cast<char>('a' + b % 26);
        }
        break;
      case 5:
        if (!slots.empty()) slots.erase(slots.begin() + a % slots.size());
        break;
      case 6:
        if (!slots.empty()) slots[a % slots.size()].index = static_cast<int8_t>(b);
        break;
      case 7:
        if (!slots.empty() && !model.empty())
          slots[a % slots.size()].parameter = model[b % model.size()].name;
        break;
      case 8:
        if (!slots.empty()) slots[a % slots.size()].step = static_cast<int8_t>(b);
        break;
      case 9:
        if (!slots.empty()) {
          torch::Tensor& t = slots[a % slots.size()].exp_avg_sq;
          if (t.numel() > 0) set_value(t, b % t.numel(), odd_value(b));
        }
        break;
      case 10:
        if (!slots.empty()) {
          bsms::AdamSlot& s = slots[a % slots.size()];
          s.max_exp_avg_sq = s.max_exp_avg_sq.defined() ? torch::Tensor() : s.exp_avg_sq.clone();
        }
        break;
      case 11:
        if (!slots.empty()) {
          torch::Tensor& t =
              b % 2 ? slots[a % slots.size()].exp_avg : slots[a % slots.size()].exp_avg_sq;
          t = t.reshape({-1}).narrow(0, 0, t.numel() > 0 ? t.numel() - 1 : 0).clone();
        }
        break;
      case 12:
        if (!c.groups.empty()) {
          bsms::AdamGroup& g = c.groups[a % c.groups.size()];
          double* fields[] = {&g.lr, &g.beta1, &g.beta2, &g.eps, &g.weight_decay};
          if (b % 7 < 5)
            *fields[b % 7] = odd_value(a);
          else if (b % 7 == 5)
            g.amsgrad = !g.amsgrad;
          else
            g.size = static_cast<int8_t>(a);
        }
        break;
      case 13:
        if (b % 2 && !c.groups.empty())
          c.groups.pop_back();
        else
          c.groups.push_back(c.groups.empty() ? bsms::AdamGroup{} : c.groups.front());
        break;
      case 14:
        if (b % 2)
          c.state.step = static_cast<int8_t>(a);
        else
          c.state.wall_s = odd_value(a);
        break;
      case 15:
        c.training = !c.training;
        break;
      case 16: {
        std::string name = "x";
        name += static_cast<char>(b % 2 ? '.' : 'a' + a % 26);
        model.push_back({name, torch::zeros({a % 4}, odd_type(b))});
        break;
      }
      default:
        if (!model.empty()) {
          torch::Tensor& t = model[a % model.size()].value;
          t = t.reshape({-1});  // same values, another rank
        }
        break;
    }
  }
}

}  // namespace

// libhdf5 1.10 leaks a block of an object header it failed to load from a damaged file
// (H5O_protect's error path, 160 bytes): libhdf5's, not bsms', and bounded per file opened.
extern "C" const char* __lsan_default_suppressions() {
  return "leak:libhdf5_serial.so\n";
}

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  torch::set_num_threads(1);
  bsms_fuzz::maybe_write_seeds(seeds);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  if (data[0] % 2 == 0) {
    load(std::string(reinterpret_cast<const char*>(data) + 1, size - 1));
    return 0;
  }
  static const bsms::CheckpointContents valid =
      bsms::read_checkpoint_contents("valid.h5", valid_image());
  bsms::CheckpointContents c = valid;
  for (auto& t : c.model) t.value = t.value.clone();
  for (auto& s : c.slots) {
    s.exp_avg = s.exp_avg.clone();
    s.exp_avg_sq = s.exp_avg_sq.clone();
    if (s.max_exp_avg_sq.defined()) s.max_exp_avg_sq = s.max_exp_avg_sq.clone();
  }
  mutate(c, data + 1, size - 1);
  const std::string path = bsms_fuzz::scratch_dir("checkpoint") + "/mutated.h5";
  try {
    bsms::write_checkpoint_contents(path, c);
  } catch (const bsms::IoError&) {
    return 0;  // a name HDF5 cannot hold ('/' or empty): no file a loader could meet
  }
  load(bsms::read_checkpoint_bytes(path));
  return 0;
}
