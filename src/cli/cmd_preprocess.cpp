// bsms preprocess: mesh -> bi-stride multilevel graph file (DESIGN.md "Multilevel graph file").
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include "cli/command.hpp"
#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "core/mesh.hpp"
#include "core/runtime.hpp"
#include "preprocess/multilevel_file.hpp"
#include "preprocess/multilevel_graph.hpp"

namespace {

struct PreprocessOptions {
  std::string mesh;
  std::string out;
  std::string seeding = "closecenter";
  std::string levels = "auto";
  uint64_t seed = 0;
  int threads = 0;
};

int parse_levels(const std::string& text) {
  if (text == "auto") return 0;
  size_t used = 0;
  long value = 0;
  try {
    value = std::stol(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != text.size() || value < 1 || value > bsms::kAutoMaxLevels) {
    throw bsms::InputError("--levels " + text + ": expected auto or an integer in 1.." +
                           std::to_string(bsms::kAutoMaxLevels));
  }
  return static_cast<int>(value);
}

// Fails before any work when the output cannot be created (InputError: exit 2), so no run ends
// in a write error after minutes of work. Creates a missing output folder.
void check_output_path(const std::string& out) {
  std::error_code ec;
  if (std::filesystem::is_directory(out, ec)) {
    throw bsms::InputError(out + ": output is a folder, expected a file");
  }
  bsms::ensure_parent_dir(out);
}

void print_table(const std::vector<bsms::LevelReport>& report) {
  std::printf("%5s %10s %12s %11s %9s %10s\n", "level", "nodes", "edges", "mean_deg", "clusters",
              "ms");
  for (const auto& row : report) {
    std::printf("%5d %10lld %12lld %11.2f %9lld %10.1f\n", row.level,
                static_cast<long long>(row.nodes), static_cast<long long>(row.edges),
                row.mean_degree, static_cast<long long>(row.clusters), row.milliseconds);
  }
}

void run_preprocess(const PreprocessOptions& options) {
  bsms::Stopwatch total;
  const int threads = bsms::set_num_threads(options.threads);
  bsms::BuildOptions build;
  build.seeding = bsms::parse_seeding(options.seeding);
  build.num_levels = parse_levels(options.levels);
  build.seed = options.seed;
  check_output_path(options.out);

  bsms::Stopwatch clock;
  const bsms::Mesh mesh = bsms::read_mesh(options.mesh);
  const double read_ms = clock.milliseconds();
  bsms::set_num_threads(options.threads);  // gmsh resets OpenMP to its own thread count
  std::vector<bsms::LevelReport> report;
  clock.reset();
  const bsms::MultilevelGraph graph = bsms::build_multilevel_graph(mesh, build, &report);
  const double build_ms = clock.milliseconds();
  clock.reset();
  bsms::write_multilevel_graph(graph, options.out);
  const double write_ms = clock.milliseconds();

  std::printf("mesh %s: %lld nodes, %lld cells (dim %d, cell dim %d)\n", options.mesh.c_str(),
              static_cast<long long>(mesh.num_nodes()), static_cast<long long>(mesh.num_cells()),
              mesh.dim, mesh.cell_dim);
  std::printf("seeding %s, %d levels (%s), %d threads\n", options.seeding.c_str(),
              graph.num_levels(), options.levels == "auto" ? "auto" : "requested", threads);
  print_table(report);
  std::printf("read %.1f ms, build %.1f ms, write %.1f ms, total %.1f ms -> %s\n", read_ms,
              build_ms, write_ms, total.milliseconds(), options.out.c_str());
}

}  // namespace

BSMS_COMMAND(
    "preprocess", "build the bi-stride multilevel graph file of a mesh", [](CLI::App& sub) {
      auto options = std::make_shared<PreprocessOptions>();
      sub.add_option("--mesh", options->mesh,
                     "mesh read by gmsh (.msh 2.2/4.1, or a .geo meshed on the fly)")
          ->required();
      sub.add_option("--out", options->out, "multilevel graph file to write (HDF5)")->required();
      sub.add_option("--seeding", options->seeding,
                     "seed per cluster: closecenter (nearest the mean position), minave (exact "
                     "minimum average BFS distance) or random")
          ->check(CLI::IsMember({"closecenter", "minave", "random"}))
          ->default_val("closecenter");
      sub.add_option(
             "--levels", options->levels,
             "number of levels including the input mesh, or auto: add a level while it "
             "has fewer nodes than the previous one, its largest cluster keeps >= 16 "
             "nodes, it has at most twice the edges of level 0, and at most 25% of the node pairs "
             "inside its clusters are edges (A^2 roughly doubles the degree per level)")
          ->default_val("auto");
      sub.add_option("--seed", options->seed, "random seeding: generator seed")->default_val(0);
      bsms::cli::add_threads_option(sub, options->threads);
      sub.callback([options] { run_preprocess(*options); });
    });
