#include "cli/programs.hpp"

#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <vector>

#include "cli/command.hpp"
#include "core/error.hpp"
#include "core/one_line.hpp"
#include "core/runtime.hpp"

namespace bsms::cli {

namespace {

constexpr HandedCommand kHanded[] = {
    {"convert-checkpoint",
     "convert an older run's LibTorch checkpoint (latest.pt) to latest.h5, for a file you trust",
     Program::kTorch},
    {"experiment",
     "hard-case experiments: heat-sticks, zero-shot, seeding, long-rollout; predictability, "
     "solver-frontier",
     Program::kTorch},
    {"generate", "generate a dataset of randomized UMLS-MPM trajectories (train/valid/test HDF5)",
     Program::kSolver},
    {"rollout", "roll a trained model out over a split; writes RUN/rollout/metrics.json",
     Program::kTorch},
    {"simulate", "run one UMLS-MPM scene and write frames (HDF5 + XDMF for ParaView)",
     Program::kSolver},
    {"train", "train BSMS-GNN or MeshGraphNets on a dataset (configs/train/*.json)",
     Program::kTorch},
};

}  // namespace

const HandedCommand* find_handed_command(const std::string& name) {
  for (const HandedCommand& c : kHanded)
    if (name == c.name) return &c;
  return nullptr;
}

const char* handed_command_help(const char* name) {
  const HandedCommand* c = find_handed_command(name);
  return c != nullptr ? c->help : "";
}

int run_in_program(Program program) {
  namespace fs = std::filesystem;
  const std::vector<std::string>& arguments = program_arguments();
  const std::string what = arguments.size() > 1 ? "'" + one_line(arguments[1]) + "'" : "this";
  const char* name = program == Program::kTorch ? "bsms-torch" : "bsms-solver";
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  const fs::path target = self.parent_path() / name;
  if (ec || ::access(target.c_str(), X_OK) != 0) {
#ifndef BSMS_WITH_TORCH
    if (program == Program::kTorch) {
      std::cerr << "bsms: " << what
                << " needs LibTorch, and this bsms was built without it (BSMS_TORCH=OFF)\n";
      return 2;
    }
#endif
    std::cerr << "bsms: " << what << " runs in " << name << ", which is missing beside "
              << (ec ? std::string("this bsms") : self.string())
              << " (an incomplete installation: cmake --install installs it)\n";
    return 1;
  }
  // Its environment is set here, so that the program starts once: LibTorch's programs need
  // OpenBLAS loaded to choose its kernels (core/runtime.hpp).
  if (program == Program::kTorch) load_blas_library();
  prepare_process_environment();
  std::vector<char*> argv;
  for (const std::string& a : arguments) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  ::execv(target.c_str(), argv.data());
  std::cerr << "bsms: cannot start " << target.string() << ": " << std::strerror(errno) << "\n";
  return 1;
}

void register_handed_commands() {
  for (const HandedCommand& c : kHanded) {
    const Program program = c.program;
    command_registry().push_back({c.name, c.help, [program](CLI::App& sub) {
                                    // Reached only when the command line starts otherwise (e.g.
                                    // `bsms --help train`): hand it on all the same.
                                    sub.allow_extras();
                                    sub.prefix_command();
                                    sub.callback(
                                        [program] { throw SilentExit(run_in_program(program)); });
                                  }});
  }
}

}  // namespace bsms::cli
