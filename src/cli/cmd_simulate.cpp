// bsms simulate SCENE.json --out DIR: runs one UMLS-MPM scene and writes DIR/frames.h5 + .xdmf.
#include <iostream>

#include "cli/command.hpp"
#include "core/runtime.hpp"
#include "data/mpm/simulation.hpp"

namespace {

struct SimulateOptions {
  std::string scene;
  std::string out;
  std::vector<std::string> sets;
  int threads = 0;
};

}  // namespace

BSMS_COMMAND(
    "simulate", "run one UMLS-MPM scene and write frames (HDF5 + XDMF for ParaView)",
    [](CLI::App& sub) {
      auto options = std::make_shared<SimulateOptions>();
      sub.add_option("scene", options->scene, "scene JSON file (configs/scenes/)")->required();
      sub.add_option("--out", options->out, "output folder: frames.h5, frames.xdmf, scene.json")
          ->required();
      bsms::cli::add_set_option(sub, options->sets);
      bsms::cli::add_threads_option(sub, options->threads);
      sub.callback([options] {
        const bsms::mpm::Scene scene = bsms::mpm::load_scene(options->scene, options->sets);
        const int threads = bsms::set_num_threads(options->threads);
        std::cerr << "simulate: " << options->scene << " (" << scene.dim << "D, kernel "
                  << bsms::mpm::to_string(scene.solver.kernel) << ", transfer "
                  << bsms::mpm::to_string(scene.solver.transfer) << ", " << threads
                  << " threads)\n";
        const bsms::mpm::SimulationSummary summary =
            bsms::mpm::simulate_scene(scene, options->out, true);
        std::cout << "simulate: " << summary.summary_line() << "\n"
                  << "simulate: wrote " << options->out << "/frames.h5 and frames.xdmf\n";
      });
    });
