// `bsms info` on checkpoints (bsms-torch only): reading a checkpoint's tensors needs LibTorch.
#include <torch/torch.h>

#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>

#include "cli/command.hpp"
#include "models/checkpoint.hpp"

namespace {

// Digest of a checkpoint's tensors and settings: names, types, shapes and bytes (FNV-1a, 64
// bits), so that two checkpoints can be compared bit for bit (e.g. a resumed run with an
// uninterrupted one).
struct Digest {
  int64_t tensors = 0;
  int64_t values = 0;  // tensor elements
  uint64_t hash = 0xcbf29ce484222325ull;
  void add(const void* data, size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < n; ++i) hash = (hash ^ p[i]) * 0x100000001b3ull;
  }
  void add(const std::string& text) { add(text.data(), text.size() + 1); }
  template <class T>
  void add_value(T x) {
    add(&x, sizeof x);
  }
  void add(const std::string& name, const torch::Tensor& t) {
    if (!t.defined()) return;
    add(name);
    add(std::string(c10::toString(t.scalar_type())));
    for (int64_t size : t.sizes()) add_value(size);
    add(t.data_ptr(), t.nbytes());
    ++tensors;
    values += t.numel();
  }
};

std::string hex(uint64_t h) {
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(h));
  return text;
}

// A checkpoint (training or module): step, losses, and digests of the model's and the
// optimizer's state, after the same checks as every load (bsms::read_checkpoint_contents).
std::string checkpoint_summary(const std::string& path, const std::string& indent) {
  const bsms::CheckpointContents c =
      bsms::read_checkpoint_contents(path, bsms::read_checkpoint_bytes(path));
  Digest model, optimizer;
  for (const auto& t : c.model) model.add(t.name, t.value);
  for (const auto& g : c.groups) {
    for (double x : {g.lr, g.beta1, g.beta2, g.eps, g.weight_decay}) optimizer.add_value(x);
    optimizer.add_value(static_cast<int64_t>(g.amsgrad));
    optimizer.add_value(g.size);
  }
  for (const auto& a : c.slots) {
    const std::string at = "state/" + std::to_string(a.index) + "/";
    optimizer.add(at + a.parameter);
    optimizer.add_value(a.step);
    optimizer.add(at + "exp_avg", a.exp_avg);
    optimizer.add(at + "exp_avg_sq", a.exp_avg_sq);
    optimizer.add(at + "max_exp_avg_sq", a.max_exp_avg_sq);
  }
  std::ostringstream out;
  out << indent << path << ": bsms " << (c.training ? "training" : "module")
      << " checkpoint (format version " << bsms::kCheckpointVersion << ")\n";
  if (c.training) {
    const bsms::TrainingState& s = c.state;
    out << indent << "  step " << s.step << ", wall time " << s.wall_s << " s";
    if (!std::isnan(s.loss))
      out << ", loss " << s.loss << ", valid loss " << s.valid_loss << " (zero prediction "
          << s.valid_zero_prediction << ")";
    out << '\n';
  }
  out << indent << "  model: " << model.tensors << " tensors, " << model.values
      << " values, digest " << hex(model.hash) << '\n';
  if (c.training)
    out << indent << "  optimizer: " << c.groups.size() << " group(s), " << optimizer.tensors
        << " tensors, " << optimizer.values << " values, digest " << hex(optimizer.hash) << '\n';
  if (!c.ema.empty()) {
    Digest ema;
    for (const auto& t : c.ema) ema.add(t.name, t.value);
    out << indent << "  parameter average (predictions use it): decay " << c.ema_decay << ", "
        << c.ema_updates << " updates, " << ema.tensors << " tensors, " << ema.values
        << " values, digest " << hex(ema.hash) << '\n';
  }
  return out.str();
}

const bool checkpoint_summary_registered =
    (bsms::cli::checkpoint_describer() = &checkpoint_summary, true);

}  // namespace
