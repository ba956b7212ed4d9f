// bsms: the front end (programs.hpp). Runs info, report, export and preprocess itself, without
// LibTorch or libgmsh, and hands every other command to the program that has what it needs.
#include <cstring>
#include <string>

#include "cli/command.hpp"
#include "cli/programs.hpp"
#include "core/runtime.hpp"

int main(int argc, char** argv) {
  bsms::cli::program_arguments().assign(argv, argv + argc);
  // The command is the first word that is not an option (bsms's own options come before it).
  for (int i = 1; i < argc; ++i) {
    if (argv[i][0] == '-') continue;
    if (const bsms::cli::HandedCommand* c = bsms::cli::find_handed_command(argv[i]))
      return bsms::cli::run_in_program(c->program);
    break;
  }
  // --version names the BLAS kernels that bsms-torch runs: load the library as it would be.
  for (int i = 1; i < argc; ++i)
    if (std::strcmp(argv[i], "--version") == 0) bsms::load_blas_library();
  // OpenMP's wait policy (and OpenBLAS's kernels when loaded), before either starts.
  bsms::ensure_process_environment(argv);
  bsms::tune_allocator();
  bsms::cli::register_handed_commands();
  return bsms::cli::run_cli(argc, argv);
}
