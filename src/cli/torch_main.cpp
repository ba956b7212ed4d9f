// bsms-torch: every bsms command, with LibTorch (programs.hpp); the front end starts it for
// train, rollout, experiment, convert-checkpoint and info on runs and checkpoints.
#include "cli/command.hpp"
#include "core/runtime.hpp"

int main(int argc, char** argv) {
  // OpenMP's wait policy and OpenBLAS's kernels, before either library starts (core/runtime.hpp):
  // the front end has set them, so this re-executes only when started on its own.
  bsms::ensure_process_environment(argv);
  bsms::tune_allocator();
  return bsms::cli::run_cli(argc, argv);
}
