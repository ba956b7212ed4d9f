// Older bsms wrote RUN/checkpoints/latest.pt, a LibTorch archive. Loading one compiles and runs
// TorchScript code from the file and trusts its storage offsets, so bsms no longer loads them
// anywhere else: this converts one, once, for a file the user trusts.
#pragma once

#include <string>

namespace bsms {

struct ConvertedCheckpoint {
  std::string from;  // RUN/checkpoints/latest.pt (kept)
  std::string to;    // RUN/checkpoints/latest.h5
  int64_t step = 0;
};

// Reads RUN/checkpoints/latest.pt into the model RUN/config.json describes and its Adam state,
// and writes RUN/checkpoints/latest.h5 (atomically), which is then read back through the
// validating loader. InputError when the run has no latest.pt, already has a latest.h5, or the
// archive does not fit the run's model.
ConvertedCheckpoint convert_torch_checkpoint(const std::string& run);

}  // namespace bsms
