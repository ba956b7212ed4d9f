// checkpoint_edit IN OUT OP [ENTRY]: writes a copy of the checkpoint IN to OUT with one defect
// that the HDF5 file and the tensor digests do not reveal, for the bad-input corpus
// (tests/cli/bad_input.sh) to check what the loader says of it. OP is one of
//   drop ENTRY      the model entry ENTRY unlinked from the written file (as damage would: the
//                   file's entry count still counts it)
//   reshape ENTRY   the model entry ENTRY one element longer, flattened
//   nan ENTRY       the first value of the model entry ENTRY set to NaN
//   extra ENTRY     a model entry ENTRY added (a copy of the first one)
//   step N          the training step set to N
// Exit 0 when written, 2 when IN cannot be read or OP is unknown.
#include <torch/torch.h>

#include <cmath>
#include <iostream>
#include <stdexcept>
#include <string>

#include "core/hdf5_file.hpp"
#include "models/checkpoint.hpp"

int main(int argc, char** argv) {
  if (argc != 5) {
    std::cerr << "usage: checkpoint_edit IN OUT drop|reshape|nan|extra|step ENTRY_OR_VALUE\n";
    return 2;
  }
  const std::string in = argv[1], out = argv[2], op = argv[3], arg = argv[4];
  try {
    bsms::CheckpointContents c =
        bsms::read_checkpoint_contents(in, bsms::read_checkpoint_bytes(in));
    auto entry = [&]() -> torch::Tensor& {
      for (auto& t : c.model)
        if (t.name == arg) return t.value;
      throw std::runtime_error(in + ": no model entry " + arg);
    };
    if (op == "drop") {
      entry();
    } else if (op == "reshape") {
      torch::Tensor& t = entry();
      t = torch::cat({t.reshape({-1}), torch::zeros({1}, t.options())});
    } else if (op == "nan") {
      torch::Tensor& t = entry();
      t.reshape({-1})[0] = std::nan("");
    } else if (op == "extra") {
      c.model.push_back({arg, c.model.front().value});
    } else if (op == "step") {
      c.state.step = std::stoll(arg);
    } else {
      std::cerr << "checkpoint_edit: unknown operation " << op << "\n";
      return 2;
    }
    bsms::write_checkpoint_contents(out, c);
    if (op == "drop") {
      bsms::H5File f(out, bsms::H5File::Mode::kReadWrite);
      f.remove("/model/" + arg);
      f.close();
    }
  } catch (const std::exception& e) {
    std::cerr << "checkpoint_edit: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
