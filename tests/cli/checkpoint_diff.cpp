// checkpoint_diff A.h5 B.h5 TOL: compares the model tensors (parameters and buffers; the optimizer
// state and the step aside) of two training checkpoints. Prints the largest |a - b| / (|b| + 1e-3)
// and the tensor it is in; exit 0 when it is at most TOL and both hold the same tensors, 1 when
// not, 2 when a file cannot be read. The distributed test uses it (2 ranks x b = 1 rank x 2b).
#include <torch/torch.h>

#include <iostream>
#include <map>
#include <string>

#include "models/checkpoint.hpp"

namespace {

// The model tensors of a checkpoint, read (and checked) as every bsms load reads them.
std::map<std::string, torch::Tensor> model_tensors(const std::string& path) {
  std::map<std::string, torch::Tensor> out;
  for (const auto& t :
       bsms::read_checkpoint_contents(path, bsms::read_checkpoint_bytes(path)).model)
    out[t.name] = t.value.to(torch::kFloat64);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::cerr << "usage: checkpoint_diff A.h5 B.h5 TOL\n";
    return 2;
  }
  std::map<std::string, torch::Tensor> a, b;
  try {
    a = model_tensors(argv[1]);
    b = model_tensors(argv[2]);
  } catch (const std::exception& e) {
    std::cerr << "checkpoint_diff: cannot read: " << e.what() << "\n";
    return 2;
  }
  const double tol = std::stod(argv[3]);
  if (a.size() != b.size() || a.empty()) {
    std::cerr << "checkpoint_diff: " << a.size() << " against " << b.size() << " tensors\n";
    return 1;
  }
  double worst = 0.0;
  std::string where;
  for (const auto& [name, ta] : a) {
    const auto it = b.find(name);
    if (it == b.end() || it->second.sizes() != ta.sizes()) {
      std::cerr << "checkpoint_diff: " << name << " is missing or has another shape in B\n";
      return 1;
    }
    if (ta.numel() == 0) continue;
    const double d = ((ta - it->second).abs() / (it->second.abs() + 1e-3)).max().item<double>();
    if (!(d <= worst)) {
      worst = d;
      where = name;
    }
  }
  std::cout << "max relative difference " << worst << " (" << where << "), " << a.size()
            << " tensors\n";
  return worst <= tol ? 0 : 1;
}
