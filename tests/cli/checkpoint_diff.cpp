// checkpoint_diff A.pt B.pt TOL: compares the model tensors (parameters and buffers; the optimizer
// state and the step aside) of two training checkpoints. Prints the largest |a - b| / (|b| + 1e-3)
// and the tensor it is in; exit 0 when it is at most TOL and both hold the same tensors, 1 when
// not, 2 when a file cannot be read. The distributed test uses it (2 ranks x b = 1 rank x 2b).
#include <torch/serialize.h>
#include <torch/torch.h>

#include <iostream>
#include <map>
#include <string>

namespace {

void collect(torch::serialize::InputArchive& archive, const std::string& prefix,
             std::map<std::string, torch::Tensor>& out) {
  for (const std::string& key : archive.keys()) {
    if (prefix.empty() &&
        (key == "optimizer" || key == "step" || key == "wall_s" || key == "losses"))
      continue;
    torch::Tensor t;
    if (archive.try_read(key, t)) {
      out[prefix + key] = t.to(torch::kFloat64);
      continue;
    }
    torch::serialize::InputArchive sub;
    if (archive.try_read(key, sub)) collect(sub, prefix + key + ".", out);
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::cerr << "usage: checkpoint_diff A.pt B.pt TOL\n";
    return 2;
  }
  std::map<std::string, torch::Tensor> a, b;
  try {
    torch::serialize::InputArchive archive_a, archive_b;
    archive_a.load_from(argv[1]);
    archive_b.load_from(argv[2]);
    collect(archive_a, "", a);
    collect(archive_b, "", b);
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
