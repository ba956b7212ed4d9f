// bsms preprocess: mesh -> bi-stride multilevel graph file (docs/design.md "Multilevel graph
// file").
#include <cstdio>
#include <filesystem>
#include <memory>
#include <set>
#include <string>

#include "cli/command.hpp"
#include "core/config.hpp"
#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "core/mesh.hpp"
#include "core/one_line.hpp"
#include "core/runtime.hpp"
#include "data/dataset/dataset.hpp"
#include "pipeline/graphs/graph_cache.hpp"
#include "preprocess/multilevel_file.hpp"
#include "preprocess/multilevel_graph.hpp"

namespace {

struct PreprocessOptions {
  std::string mesh;
  std::string data;
  std::string out;
  std::string seeding = "closecenter";
  std::string levels = "auto";
  std::string thinning = "auto";
  uint64_t seed = 0;
  int threads = 0;
  bsms::cli::GeoOptions geo;
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
    throw bsms::InputError("--levels " + bsms::truncate_for_message(text) +
                           ": expected auto or an integer in 1.." +
                           std::to_string(bsms::kAutoMaxLevels));
  }
  return static_cast<int>(value);
}

// Fails before any work when the output cannot be created (InputError: exit 2), so no run ends
// in a write error after minutes of work. Creates nothing: the writer creates a missing output
// folder, so a refused input leaves no empty folder behind.
void check_output_path(const std::string& out) {
  std::error_code ec;
  if (std::filesystem::is_directory(out, ec)) {
    throw bsms::InputError(out + ": output is a folder, expected a file");
  }
  const std::filesystem::path parent = std::filesystem::path(out).parent_path();
  bsms::cli::require_creatable_dir(parent.empty() ? "." : parent.string());
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

// Every mesh topology of a dataset folder's splits, all with the same level count (the count
// `auto` picks for the first training mesh, as training does), into the cache folder that
// `bsms train` and `bsms rollout` read.
void run_preprocess_data(const PreprocessOptions& options) {
  namespace fs = std::filesystem;
  bsms::Stopwatch total;
  // Every option checked before a dataset is opened.
  int levels = parse_levels(options.levels);
  const bsms::Seeding seeding = bsms::parse_seeding(options.seeding);
  const int threads = bsms::set_num_threads(options.threads);
  const std::string out =
      options.out.empty() ? (fs::path(options.data) / "multilevel").string() : options.out;
  std::vector<bsms::Dataset> splits;
  // train is required; valid and test when present (a broken one is an error, not skipped).
  for (const char* split : {"train", "valid", "test"}) {
    if (std::string(split) == "train" || bsms::Dataset::has_split(options.data, split))
      splits.push_back(bsms::Dataset::open_split(options.data, split));
  }
  if (levels == 0) levels = bsms::auto_levels(splits[0].mesh(0), seeding);
  bsms::cli::require_creatable_dir(out);
  const bsms::cli::RemoveOnFailure cleanup(out);
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec || !fs::is_directory(out))
    throw bsms::InputError(out + ": cannot create the output folder");
  // The cache reuses an entry already in `out` that matches (so a stopped run resumes) and
  // builds and writes the others, exactly as training's first use would.
  bsms::MultilevelCache cache(seeding, levels, {out}, options.seed, /*require_write=*/true);
  std::set<std::string> done;
  std::printf("%-18s %8s %10s %12s %10s\n", "topology", "levels", "nodes", "edges(L0)", "ms");
  for (const auto& d : splits) {
    for (int64_t t = 0; t < d.num_trajectories(); ++t) {
      const auto& mesh = d.mesh(t);
      if (!done.insert(bsms::topology_key(mesh)).second) continue;
      bsms::Stopwatch clock;
      const bsms::CachedMultilevel graphs = cache.load_or_build(mesh);
      const bsms::GraphLevel& finest = graphs.multilevel.levels[0];
      char ms[32];
      std::snprintf(ms, sizeof ms, "%.1f", clock.milliseconds());
      std::printf("%-18s %8d %10lld %12lld %10s\n", graphs.key.c_str(),
                  graphs.multilevel.num_levels(), static_cast<long long>(finest.num_nodes()),
                  static_cast<long long>(finest.graph.num_edges()),
                  graphs.from_cache ? "cached" : ms);
    }
  }
  std::printf("%zu topologies, %d levels, seeding %s, %d threads, %.1f ms -> %s\n", done.size(),
              levels, options.seeding.c_str(), threads, total.milliseconds(), out.c_str());
}

void run_preprocess(const PreprocessOptions& options) {
  if (!options.data.empty()) return run_preprocess_data(options);
  if (options.mesh.empty()) throw bsms::InputError("preprocess: give --mesh FILE or --data DIR");
  if (options.out.empty()) throw bsms::InputError("preprocess --mesh needs --out FILE.h5");
  bsms::Stopwatch total;
  const int threads = bsms::set_num_threads(options.threads);
  bsms::BuildOptions build;
  build.seeding = bsms::parse_seeding(options.seeding);
  build.num_levels = parse_levels(options.levels);
  build.rng_seed = options.seed;
  build.thinning = bsms::parse_thinning(options.thinning);
  check_output_path(options.out);

  bsms::Stopwatch clock;
  const bsms::Mesh mesh = bsms::read_mesh(options.mesh);
  const double read_ms = clock.milliseconds();
  // The graph needs only the connectivity, so degenerate cells are a warning here; the solver,
  // which integrates over them, refuses them.
  const bsms::BadCells bad = bsms::find_bad_cells(mesh);
  if (bad.count() > 0)
    std::fprintf(stderr, "preprocess: warning: %s: %s; the graph uses the connectivity only\n",
                 bsms::one_line(options.mesh, 300).c_str(), bad.describe().c_str());
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
  std::printf("seeding %s, %d levels (%s), coarse levels %s, %d threads\n", options.seeding.c_str(),
              graph.num_levels(), options.levels == "auto" ? "auto" : "requested",
              graph.thinned ? "thinned" : "exact A^2", threads);
  print_table(report);
  std::printf("read %.1f ms, build %.1f ms, write %.1f ms, total %.1f ms -> %s\n", read_ms,
              build_ms, write_ms, total.milliseconds(), options.out.c_str());
}

}  // namespace

BSMS_COMMAND(
    "preprocess", "build the bi-stride multilevel graph file of a mesh", [](CLI::App& sub) {
      auto options = std::make_shared<PreprocessOptions>();
      auto* mesh = sub.add_option("--mesh", options->mesh,
                                  "mesh: .msh 2.2/4.1 (read directly), or any file gmsh reads (a "
                                  ".geo is meshed on the fly)");
      auto* data = sub.add_option("--data", options->data,
                                  "dataset folder: every mesh topology of its splits, written to "
                                  "--out (default DATA/multilevel/) where bsms train finds them");
      mesh->excludes(data);
      sub.add_option("--out", options->out,
                     "multilevel graph file to write (HDF5); with --data, a folder");
      sub.add_option("--seeding", options->seeding,
                     "seed per cluster: closecenter (nearest the mean position), minave (exact "
                     "minimum average BFS distance) or random")
          ->check(CLI::IsMember(bsms::seeding_names()))
          ->default_val("closecenter");
      sub.add_option(
             "--levels", options->levels,
             "number of levels including the input mesh, or auto: add a (thinned) level "
             "while it has fewer nodes than the previous one, its largest cluster keeps "
             ">= 16 nodes, all coarse levels together have at most 2x the edges of level 0, "
             "and at most 25% of the node pairs inside its clusters are edges")
          ->default_val("auto");
      sub.add_option("--thinning", options->thinning,
                     "coarse levels: on = keep each node's nearest and farthest A^2 neighbour "
                     "per direction cone once its degree exceeds 2 x cones (8 in 2D, 14 in 3D), "
                     "off = exact A^2 (docs/design.md), auto = on with --levels auto (--mesh only)")
          ->check(CLI::IsMember({"auto", "on", "off"}))
          ->default_val("auto");
      sub.add_option("--seed", options->seed, "random seeding: generator seed")
          ->check(CLI::NonNegativeNumber)
          ->default_val(0);
      bsms::cli::add_threads_option(sub, options->threads);
      bsms::cli::add_geo_options(sub, options->geo);
      sub.callback([options] {
        options->geo.apply();
        run_preprocess(*options);
      });
    });
