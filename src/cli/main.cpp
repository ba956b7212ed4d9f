// bsms: entry point. Sets up the runtime (OpenMP wait policy, threads), dispatches subcommands and
// turns errors into one clear line: InputError -> exit 2, NumericalError -> exit 3.
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <iostream>

#include "cli/command.hpp"
#include "core/error.hpp"
#include "core/runtime.hpp"

namespace bsms::cli {

std::vector<Command>& command_registry() {
  static std::vector<Command> registry;
  return registry;
}

void add_threads_option(CLI::App& sub, int& threads) {
  sub.add_option("--threads", threads,
                 "worker threads (OpenMP and LibTorch); 0 = all hardware threads")
      ->check(CLI::Range(0, 4096))
      ->default_val(0);
}

void add_set_option(CLI::App& sub, std::vector<std::string>& sets) {
  sub.add_option("--set", sets, "override a config value: key.path=value (repeatable)")
      ->type_name("KEY=VALUE");
}

}  // namespace bsms::cli

namespace {

// libgomp reads OMP_WAIT_POLICY once, when it loads: spin-waiting threads steal the second core
// from serial work (measured 1.8x slower training on 2 cores, DESIGN.md). Re-execute with PASSIVE
// unless the user chose a policy.
void ensure_passive_omp_wait(char** argv) {
  if (std::getenv("OMP_WAIT_POLICY") != nullptr) return;
  setenv("OMP_WAIT_POLICY", "PASSIVE", 1);
  execv("/proc/self/exe", argv);
  // If re-exec fails we continue with the default policy: slower, still correct.
}

}  // namespace

int main(int argc, char** argv) {
  ensure_passive_omp_wait(argv);
  bsms::tune_allocator();

  CLI::App app{
      "bsms: Bi-Stride Multi-Scale GNNs for mesh-based simulation (UMLS-MPM data, LibTorch)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "bsms 0.1");
  auto& registry = bsms::cli::command_registry();
  std::sort(registry.begin(), registry.end(),
            [](const auto& a, const auto& b) { return a.name < b.name; });
  for (const auto& command : registry) {
    CLI::App* sub = app.add_subcommand(command.name, command.help);
    command.setup(*sub);
  }

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "bsms: " << e.what() << " (see --help)\n";
    return 2;
  } catch (const bsms::InputError& e) {
    std::cerr << "bsms: error: " << e.what() << "\n";
    return 2;
  } catch (const bsms::NumericalError& e) {
    std::cerr << "bsms: numerical failure: " << e.what() << "\n";
    return 3;
  } catch (const bsms::IoError& e) {
    std::cerr << "bsms: I/O error: " << e.what() << "\n";
    return 4;
  } catch (const std::exception& e) {
    std::cerr << "bsms: internal error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
