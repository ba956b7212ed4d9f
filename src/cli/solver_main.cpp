// bsms-solver: simulate and generate, with libgmsh and without LibTorch (programs.hpp).
#include "cli/command.hpp"
#include "core/runtime.hpp"

int main(int argc, char** argv) {
  bsms::ensure_process_environment(argv);
  bsms::tune_allocator();
  return bsms::cli::run_cli(argc, argv);
}
