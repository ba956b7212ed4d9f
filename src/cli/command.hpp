// Subcommand registry: each src/cli/cmd_*.cpp registers itself with BSMS_COMMAND, so adding a
// subcommand touches one file. Registration order does not matter; --help lists by name.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <vector>

namespace bsms {
struct ProjectionOptions;
}

namespace bsms::cli {

struct Command {
  std::string name;
  std::string help;
  // Adds options to `sub` and sets its callback. Errors are thrown (InputError -> exit 2).
  std::function<void(CLI::App& sub)> setup;
};

std::vector<Command>& command_registry();

// Parses the command line against the registered commands and runs the chosen one; returns the
// exit code (see --help's footer). Each program's main calls it after setting up its process.
int run_cli(int argc, char** argv);

struct CommandRegistrar {
  explicit CommandRegistrar(Command command) { command_registry().push_back(std::move(command)); }
};

// The command line this process was started with (argv), e.g. to start it again as ranks.
std::vector<std::string>& program_arguments();

// Describes a training or module checkpoint for `bsms info`, with `indent` before each line. Set in
// bsms-torch only (cmd_info_checkpoint.cpp); where it is null, info hands the command to
// bsms-torch (programs.hpp).
using CheckpointDescriber = std::string (*)(const std::string& path, const std::string& indent);
CheckpointDescriber& checkpoint_describer();

// Options most subcommands share.
void add_threads_option(CLI::App& sub, int& threads);
void add_set_option(CLI::App& sub, std::vector<std::string>& sets);
// The one-line message for a command line whose first words name no subcommand where one is
// required (e.g. "bsms trian"), walking nested subcommands; empty when they all exist.
std::string unknown_subcommand(const CLI::App& app, const std::vector<std::string>& args);
// --project LIST: constraints projected after each predicted step (core/physical_projection.hpp).
void add_projection_option(CLI::App& sub, ProjectionOptions& projection);

// Options of the subcommands that read a mesh file the user names, which may be a gmsh script
// (preprocess --mesh, scenes' mesh bodies and backgrounds in simulate): --geo-time-limit,
// --geo-memory-limit and --allow-geo-commands (core/gmsh_worker.hpp). apply() sets them
// process-wide over BSMS_GEO_TIME_LIMIT / BSMS_GEO_MEMORY_LIMIT; call it before reading.
struct GeoOptions {
  double time_limit_s = 0.0;      // 0: the environment's or 120 s
  double memory_limit_gib = 0.0;  // 0: the environment's or half the machine's memory
  bool allow_commands = false;
  void apply() const;
};
void add_geo_options(CLI::App& sub, GeoOptions& options);

// Throws InputError (exit 2) when the folder `dir` could not be created: it, or the nearest of
// its ancestors that exists, is not a folder. Creates nothing, so a run refused later leaves no
// empty output folder behind.
void require_creatable_dir(const std::string& dir);

// Removes `path` (a folder this command created) when the command fails, unless `keep` says the
// partial output is worth keeping (e.g. resumable work). Construct before the work starts.
class RemoveOnFailure {
 public:
  explicit RemoveOnFailure(std::string path, std::function<bool()> keep = {});
  ~RemoveOnFailure();
  RemoveOnFailure(const RemoveOnFailure&) = delete;
  RemoveOnFailure& operator=(const RemoveOnFailure&) = delete;

 private:
  std::string path_;
  bool existed_;
  int uncaught_;
  std::function<bool()> keep_;
};

}  // namespace bsms::cli

#define BSMS_CONCAT_INNER(a, b) a##b
#define BSMS_CONCAT(a, b) BSMS_CONCAT_INNER(a, b)
#define BSMS_COMMAND(name, help, setup) \
  static ::bsms::cli::CommandRegistrar BSMS_CONCAT(bsms_command_, __COUNTER__)({name, help, setup})
