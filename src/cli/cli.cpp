// What the three bsms programs share (programs.hpp): the options common to subcommands, and
// run_cli, which dispatches to the registered subcommands and turns errors into one clear line:
// InputError -> exit 2, NumericalError -> exit 3, IoError -> 4, DistributedError (a lost rank) ->
// 5, any other exception -> 1 ("internal error": a bug). Every message goes through one_line
// (core/one_line.hpp): control characters escaped, length capped.
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <iostream>

#include "cli/command.hpp"
#include "core/config.hpp"
#include "core/error.hpp"
#include "core/gmsh_worker.hpp"
#include "core/one_line.hpp"
#include "core/physical_projection.hpp"
#include "core/runtime.hpp"

namespace bsms::cli {

std::vector<Command>& command_registry() {
  static std::vector<Command> registry;
  return registry;
}

CheckpointDescriber& checkpoint_describer() {
  static CheckpointDescriber describer = nullptr;
  return describer;
}

std::vector<std::string>& program_arguments() {
  static std::vector<std::string> args;
  return args;
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

void add_projection_option(CLI::App& sub, ProjectionOptions& projection) {
  sub.add_option_function<std::string>(
         "--project",
         [&projection](const std::string& list) {
           try {
             projection = parse_projection(list);
           } catch (const std::invalid_argument& e) {
             throw CLI::ValidationError("--project", e.what());
           }
         },
         "constraints projected after each predicted step: walls (nodes inside the box), cells "
         "(no cell turned inside out), contact (no node inside another body), or all; "
         "comma-separated")
      ->type_name("LIST");
}

namespace {

// CLI11's number checks let NaN through (every comparison with it is false): a number > 0, finite,
// at most `max`.
CLI::Validator positive_at_most(double max, const std::string& unit) {
  return CLI::Validator(
      [max, unit](std::string& text) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (text.empty() || end != text.c_str() + text.size() || !(v > 0.0 && v <= max))
          return "'" + text.substr(0, 32) +
                 "': expected a number > 0 and <= " + std::to_string(static_cast<long long>(max)) +
                 " (" + unit + ")";
        return "";
      },
      unit);
}

}  // namespace

void add_geo_options(CLI::App& sub, GeoOptions& options) {
  sub.add_option("--geo-time-limit", options.time_limit_s,
                 "seconds gmsh may take to read and mesh one file (default 120, or "
                 "BSMS_GEO_TIME_LIMIT)")
      ->check(positive_at_most(1e7, "SECONDS"));
  sub.add_option("--geo-memory-limit", options.memory_limit_gib,
                 "GiB of memory gmsh may use on one file (default half the machine's memory, or "
                 "BSMS_GEO_MEMORY_LIMIT)")
      ->check(positive_at_most(1e6, "GIB"));
  sub.add_flag("--allow-geo-commands", options.allow_commands,
               "run the commands of .geo scripts that bsms refuses (SystemCall, Exit, Include, "
               "Save, ...): at your own risk, only for scripts you trust");
}

void GeoOptions::apply() const {
  GmshLimits limits = gmsh_limits_from_environment();
  if (time_limit_s > 0.0) limits.time_limit_s = time_limit_s;
  if (memory_limit_gib > 0.0) limits.memory_limit_gib = memory_limit_gib;
  limits.allow_geo_commands = allow_commands;
  set_gmsh_limits(limits);
}

void require_creatable_dir(const std::string& dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::path p = fs::absolute(fs::path(dir), ec);
  if (ec) p = dir;
  for (fs::path q = p; !q.empty(); q = q.parent_path()) {
    if (fs::exists(q, ec)) {
      if (!fs::is_directory(q, ec))
        throw InputError(dir + ": cannot create the output folder (" + q.string() +
                         " is not a folder)");
      return;
    }
    if (q == q.parent_path()) return;
  }
}

RemoveOnFailure::RemoveOnFailure(std::string path, std::function<bool()> keep)
    : path_(std::move(path)), keep_(std::move(keep)) {
  std::error_code ec;
  existed_ = path_.empty() || std::filesystem::exists(path_, ec);
  uncaught_ = std::uncaught_exceptions();
}

RemoveOnFailure::~RemoveOnFailure() {
  if (existed_ || std::uncaught_exceptions() <= uncaught_) return;
  try {
    if (keep_ && keep_()) return;
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  } catch (...) {
  }
}

namespace {

size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] != b[j - 1] ? 1 : 0)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

}  // namespace

std::string unknown_subcommand(const CLI::App& app, const std::vector<std::string>& args) {
  const CLI::App* at = &app;
  std::string path = "bsms";
  for (const std::string& word : args) {
    const auto subs = at->get_subcommands([](const CLI::App*) { return true; });
    if (subs.empty() || word.empty() || word[0] == '-') return "";
    const CLI::App* next = nullptr;
    std::string names, closest;
    size_t best = std::string::npos;
    for (const CLI::App* sub : subs) {
      if (sub->get_name() == word) next = sub;
      names += (names.empty() ? "" : ", ") + sub->get_name();
      const size_t d = edit_distance(word, sub->get_name());
      if (d < best) {
        best = d;
        closest = sub->get_name();
      }
    }
    if (!next) {
      const bool near = best <= std::max<size_t>(2, word.size() / 3);
      return path + ": unknown subcommand '" + truncate_for_message(word, 100) + "'" +
             (near ? " (did you mean '" + closest + "'?)" : "") + "; expected one of: " + names;
    }
    at = next;
    path += " " + word;
  }
  return "";
}

}  // namespace bsms::cli

namespace bsms::cli {

int run_cli(int argc, char** argv) {
  program_arguments().assign(argv, argv + argc);
  CLI::App app{
      "bsms: Bi-Stride Multi-Scale GNNs for mesh-based simulation (UMLS-MPM data, LibTorch)"};
  app.require_subcommand(1);
  const std::string blas = bsms::blas_config();
  app.set_version_flag("--version", "bsms 0.1" + (blas.empty() ? "" : "\nBLAS: " + blas) +
                                        "\nmalloc: " + bsms::allocator_name());
  app.footer(
      "Exit codes: 0 success, 1 internal error (a bug to report), 2 bad input, 3 numerical "
      "failure, 4 I/O failure, 5 distributed training lost a rank.");
  auto& registry = command_registry();
  std::sort(registry.begin(), registry.end(),
            [](const auto& a, const auto& b) { return a.name < b.name; });
  for (const auto& command : registry) {
    CLI::App* sub = app.add_subcommand(command.name, command.help);
    command.setup(*sub);
  }

  // CLI11 answers a misspelt subcommand with "A subcommand is required": name it instead.
  const std::string unknown =
      unknown_subcommand(app, std::vector<std::string>(argv + std::min(argc, 1), argv + argc));
  if (!unknown.empty()) {
    std::cerr << bsms::one_line(unknown) << " (see --help)\n";
    return 2;
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
    std::cerr << "bsms: " << bsms::one_line(e.what()) << " (see --help)\n";
    return 2;
  } catch (const bsms::InputError& e) {
    std::cerr << "bsms: error: " << bsms::one_line(e.what()) << "\n";
    return 2;
  } catch (const bsms::NumericalError& e) {
    std::cerr << "bsms: numerical failure: " << bsms::one_line(e.what()) << "\n";
    return 3;
  } catch (const bsms::IoError& e) {
    std::cerr << "bsms: I/O error: " << bsms::one_line(e.what()) << "\n";
    return 4;
  } catch (const bsms::SilentExit& e) {
    return e.code;
  } catch (const bsms::DistributedError& e) {
    std::cerr << "bsms: distributed training stopped: " << bsms::one_line(e.what()) << "\n";
    return 5;
  } catch (const std::exception& e) {
    std::cerr << "bsms: internal error: " << bsms::one_line(e.what()) << "\n";
    return 1;
  }
  return 0;
}

}  // namespace bsms::cli
