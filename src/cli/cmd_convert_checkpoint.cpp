// bsms convert-checkpoint RUN --trust-torch-archive: an older run's LibTorch checkpoint
// (RUN/checkpoints/latest.pt) converted once to RUN/checkpoints/latest.h5.
#include <iostream>

#include "cli/command.hpp"
#include "cli/programs.hpp"
#include "core/error.hpp"
#include "pipeline/adapters/simulator.hpp"
#include "pipeline/train/legacy_checkpoint.hpp"
#include "pipeline/train/trainer.hpp"

namespace {

struct ConvertArgs {
  std::string run;
  bool trust = false;
};

BSMS_COMMAND(
    "convert-checkpoint", bsms::cli::handed_command_help("convert-checkpoint"), [](CLI::App& sub) {
      auto args = std::make_shared<ConvertArgs>();
      sub.add_option("run", args->run, "run folder holding checkpoints/latest.pt")->required();
      sub.add_flag("--trust-torch-archive", args->trust,
                   "load the LibTorch archive (this runs code from the file: only for a file "
                   "you trust, e.g. one your own older bsms wrote)");
      sub.footer(
          "Older bsms wrote RUN/checkpoints/latest.pt with LibTorch's archive format, whose\n"
          "loader compiles and runs code from the file. bsms now writes and reads\n"
          "RUN/checkpoints/latest.h5 (HDF5, validated on load) and refuses latest.pt; this\n"
          "command converts it once (through the model RUN/config.json describes) and keeps\n"
          "latest.pt, which can be removed once the run is continued or rolled out.");
      sub.callback([args] {
        const std::string legacy =
            bsms::legacy_checkpoint_path(bsms::run_checkpoint_path(args->run));
        if (!args->trust)
          throw bsms::InputError(legacy +
                                 ": converting loads a LibTorch archive, which runs code from "
                                 "the file; pass --trust-torch-archive if you trust it");
        const bsms::ConvertedCheckpoint done = bsms::convert_torch_checkpoint(args->run);
        std::cout << "converted " << done.from << " (step " << done.step << ") to " << done.to
                  << "; " << done.from << " is kept\n";
      });
    });

}  // namespace
