// bsms simulate SCENE.json --out DIR: runs one UMLS-MPM scene and writes DIR/frames.h5 + .xdmf.
#include <filesystem>
#include <iostream>

#include "cli/command.hpp"
#include "cli/programs.hpp"
#include "core/error.hpp"
#include "core/runtime.hpp"
#include "data/mpm/scene_config.hpp"
#include "data/mpm/scene_size.hpp"
#include "data/mpm/simulation.hpp"

namespace {

struct SimulateOptions {
  std::string scene;
  std::string out;
  std::vector<std::string> sets;
  int threads = 0;
  bsms::cli::GeoOptions geo;
};

}  // namespace

BSMS_COMMAND("simulate", bsms::cli::handed_command_help("simulate"), [](CLI::App& sub) {
  auto options = std::make_shared<SimulateOptions>();
  sub.add_option("scene", options->scene, "scene JSON file (configs/scenes/)")->required();
  sub.add_option("--out", options->out, "output folder: frames.h5, frames.xdmf, scene.json")
      ->required();
  bsms::cli::add_set_option(sub, options->sets);
  bsms::cli::add_threads_option(sub, options->threads);
  bsms::cli::add_geo_options(sub, options->geo);
  sub.callback([options] {
    options->geo.apply();
    const bsms::mpm::Scene scene = bsms::mpm::load_scene(options->scene, options->sets);
    // Refused before any work: a size typo, an output folder that cannot be created (made
    // now, and removed again if the run fails).
    bsms::mpm::check_scene_size(scene);
    bsms::cli::require_creatable_dir(options->out);
    const bsms::cli::RemoveOnFailure cleanup(options->out);
    std::error_code ec;
    std::filesystem::create_directories(options->out, ec);
    if (ec || !std::filesystem::is_directory(options->out))
      throw bsms::InputError(options->out + ": cannot create the output folder (" +
                             (ec ? ec.message() : std::string("not a folder")) + ")");
    const int threads = bsms::set_num_threads(options->threads);
    // On stdout with the summary: stderr holds the progress and, on failure, one error line.
    std::cout << "simulate: " << options->scene << " (" << scene.dim << "D, kernel "
              << bsms::mpm::to_string(scene.solver.kernel) << ", transfer "
              << bsms::mpm::to_string(scene.solver.transfer) << ", " << threads << " threads)"
              << std::endl;
    const bsms::mpm::SimulationSummary summary =
        bsms::mpm::simulate_scene(scene, options->out, true);
    std::cout << "simulate: " << summary.summary_line() << "\n"
              << "simulate: wrote " << options->out << "/frames.h5 and frames.xdmf\n";
  });
});
