// The bsms command line is three programs, so that each command loads only the libraries it
// needs: LibTorch alone takes ~0.6 s to load (336 shared libraries) and libgmsh ~80 ms.
// - bsms (the front end, main.cpp): info, report, export, preprocess, --help and --version
//   itself; no LibTorch, no libgmsh. Every other command it hands to one of the two below,
//   with the environment they need set (core/runtime.hpp ensure_process_environment), by
//   executing it in its place: one start-up each, no second load.
// - bsms-solver (solver_main.cpp): simulate and generate, which mesh scenes with gmsh.
// - bsms-torch (torch_main.cpp): train, rollout, experiment, convert-checkpoint, and info on a
//   run or checkpoint; it also runs every other command, so it works on its own.
// The helper programs lie beside bsms (the build folder, or the install's bin/).
#pragma once

#include <string>

namespace bsms::cli {

enum class Program { kSolver, kTorch };

// A command the front end hands on: its name, its one-line help (the only copy: the command's
// own registration uses it too) and the program that runs it.
struct HandedCommand {
  const char* name;
  const char* help;
  Program program;
};

// The entry of `name`, or nullptr when the front end runs it.
const HandedCommand* find_handed_command(const std::string& name);
// The help line of a handed command, for its registration in the program that runs it.
const char* handed_command_help(const char* name);

// Executes `program` (beside this executable) in place of this process with the command line
// program_arguments(), after setting the environment it needs. Returns only on failure, after
// printing one line naming what is missing; the caller exits with the returned code.
int run_in_program(Program program);

// Registers the handed commands in the front end's command table (names and help, for --help and
// for naming a misspelt command); their options are the helper program's.
void register_handed_commands();

}  // namespace bsms::cli
