// Bi-stride multilevel building: CloseCenter on structured triangulated rectangles from 10K to 1M
// nodes (22K and 243K match the original Python figures in docs/design.md: 0.39 s and 6.4 s),
// reading a 1M-node .msh written by gmsh (alone, through gmsh and directly, and plus building), and
// exact MinAve at 50K nodes.
#include <benchmark/benchmark.h>
#include <gmsh.h>
#include <omp.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <string>

#include "core/gmsh_session.hpp"
#include "core/graph.hpp"
#include "core/mesh.hpp"
#include "core/msh_reader.hpp"
#include "preprocess/contact_enhancement.hpp"
#include "preprocess/multilevel_graph.hpp"
#include "preprocess/seeding.hpp"

namespace {

using namespace bsms;

// A square of about `target` nodes, each grid cell split into two triangles.
const Mesh& rectangle_mesh(int64_t target) {
  static std::map<int64_t, Mesh> cache;
  auto it = cache.find(target);
  if (it != cache.end()) return it->second;
  const int64_t side = static_cast<int64_t>(std::llround(std::sqrt(static_cast<double>(target))));
  const int64_t nx = side - 1, ny = side - 1;
  RowMatrixXd points(side * side, 2);
  for (int64_t i = 0; i < side; ++i) {
    for (int64_t j = 0; j < side; ++j) points.row(i * side + j) << 0.01 * i, 0.01 * j;
  }
  RowMatrixXi64 cells(2 * nx * ny, 3);
  int64_t c = 0;
  for (int64_t i = 0; i < nx; ++i) {
    for (int64_t j = 0; j < ny; ++j) {
      const int64_t a = i * side + j, b = a + side, d = a + 1, e = b + 1;
      cells.row(c++) << a, b, e;
      cells.row(c++) << a, e, d;
    }
  }
  return cache.emplace(target, make_mesh(2, std::move(points), std::move(cells))).first->second;
}

void report_levels(benchmark::State& state, const std::vector<LevelReport>& report) {
  state.counters["nodes"] = static_cast<double>(report.front().nodes);
  state.counters["levels"] = static_cast<double>(report.size());
  state.counters["coarsest_nodes"] = static_cast<double>(report.back().nodes);
  state.counters["threads"] = omp_get_max_threads();
}

// Mesh graph + all levels (--levels auto), CloseCenter.
void BM_CloseCenterBuild(benchmark::State& state) {
  const Mesh& mesh = rectangle_mesh(state.range(0));
  std::vector<LevelReport> report;
  for (auto _ : state) {
    MultilevelGraph graph = build_multilevel_graph(mesh, BuildOptions{}, &report);
    benchmark::DoNotOptimize(graph.levels.data());
  }
  report_levels(state, report);
}
BENCHMARK(BM_CloseCenterBuild)
    ->Arg(10'000)
    ->Arg(22'000)
    ->Arg(100'000)
    ->Arg(243'000)
    ->Arg(1'000'000)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(3)
    ->ReportAggregatesOnly(true)
    ->Iterations(1);

// Exact MinAve seed of a 50K-node mesh (one cluster), and the whole MinAve multilevel build.
void BM_MinAveSeed(benchmark::State& state) {
  const Mesh& mesh = rectangle_mesh(state.range(0));
  const CsrGraph graph = mesh_graph(mesh);
  const ClusterNodes clusters = group_clusters(connected_components(graph));
  MinAveStats stats;
  for (auto _ : state) {
    auto seeds = min_ave_seeds(graph, clusters, &stats);
    benchmark::DoNotOptimize(seeds.data());
  }
  state.counters["nodes"] = static_cast<double>(graph.num_nodes);
  state.counters["evaluated"] = static_cast<double>(stats.evaluated);
  state.counters["bound_bfs"] = static_cast<double>(stats.bound_bfs);
  state.counters["threads"] = omp_get_max_threads();
}
BENCHMARK(BM_MinAveSeed)
    ->Arg(50'000)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(3)
    ->ReportAggregatesOnly(true)
    ->Iterations(1);

void BM_MinAveBuild(benchmark::State& state) {
  const Mesh& mesh = rectangle_mesh(state.range(0));
  BuildOptions options;
  options.seeding = Seeding::kMinAve;
  std::vector<LevelReport> report;
  for (auto _ : state) {
    MultilevelGraph graph = build_multilevel_graph(mesh, options, &report);
    benchmark::DoNotOptimize(graph.levels.data());
  }
  report_levels(state, report);
}
BENCHMARK(BM_MinAveBuild)
    ->Arg(50'000)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(3)
    ->ReportAggregatesOnly(true)
    ->Iterations(1);

// A scratch folder removed when the program ends.
struct ScratchFolder {
  ScratchFolder()
      : path(std::filesystem::temp_directory_path() /
             ("bsms-bench-" + std::to_string(::getpid()))) {
    std::filesystem::create_directories(path);
  }
  ~ScratchFolder() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
  std::filesystem::path path;
};

// Per-frame contact enhancement through all levels of a 100K-node square: a contact line, every
// node of grid column side/2 paired (both directions) with the node two columns over, as a crack
// or a contact interface gives.
void BM_ContactEnhancementAllLevels(benchmark::State& state) {
  const Mesh& mesh = rectangle_mesh(state.range(0));
  const MultilevelGraph graph = build_multilevel_graph(mesh, BuildOptions{});
  const int64_t side = static_cast<int64_t>(std::llround(std::sqrt(mesh.num_nodes())));
  EdgeList contact;
  for (int64_t j = 0; j < side; ++j) {
    const int64_t a = (side / 2) * side + j, b = a + 2 * side;
    contact.data.insert(contact.data.end(), {a, b, b, a});
  }
  int64_t coarsest = 0;
  for (auto _ : state) {
    const auto levels = enhance_contact_edges_all_levels(graph, contact);
    coarsest = levels.back().size();
    benchmark::DoNotOptimize(levels.data());
  }
  state.counters["levels"] = graph.num_levels();
  state.counters["contacts"] = static_cast<double>(contact.size());
  state.counters["coarsest_contacts"] = static_cast<double>(coarsest);
}
BENCHMARK(BM_ContactEnhancementAllLevels)
    ->Arg(100'000)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(3)
    ->ReportAggregatesOnly(true);

// A 1M-node unit square meshed by gmsh (transfinite, triangles), written as ASCII .msh 4.1.
std::string gmsh_million_node_file() {
  static ScratchFolder folder;
  static std::string path;
  if (!path.empty()) return path;
  path = (folder.path / "square_1m.msh").string();
  const int threads = omp_get_max_threads();
  GmshSession session;
  gmsh::model::add("square");
  const int n = 1000;
  const int surface = gmsh::model::occ::addRectangle(0, 0, 0, 1, 1);
  gmsh::model::occ::synchronize();
  std::vector<std::pair<int, int>> curves;
  gmsh::model::getBoundary({{2, surface}}, curves, false, false, false);
  for (const auto& curve : curves) gmsh::model::mesh::setTransfiniteCurve(curve.second, n);
  gmsh::model::mesh::setTransfiniteSurface(surface);
  gmsh::model::mesh::generate(2);
  gmsh::option::setNumber("Mesh.MshFileVersion", 4.1);
  gmsh::write(path);
  omp_set_num_threads(threads);  // gmsh sets OpenMP to its own thread count
  return path;
}

// Reading the same 1M-node .msh alone: through the gmsh library (arg 0, read_mesh_with_gmsh)
// and with the direct reader (arg 1, read_msh, what read_mesh uses for it). Run with
// --benchmark_enable_random_interleaving=true to alternate the two on a shared machine.
void BM_ReadMsh(benchmark::State& state) {
  const std::string path = gmsh_million_node_file();
  const bool direct = state.range(0) == 1;
  for (auto _ : state) {
    const Mesh mesh = direct ? read_msh(path) : read_mesh_with_gmsh(path);
    benchmark::DoNotOptimize(mesh.points.data());
  }
  state.SetLabel(direct ? "direct" : "gmsh");
}
BENCHMARK(BM_ReadMsh)
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(5)
    ->ReportAggregatesOnly(true)
    ->Iterations(1);

// The mesh check `bsms preprocess --mesh` runs after reading (find_bad_cells: zero-measure and
// inverted cells, faces shared by two cells on one side) on the same 1M-node square (2M
// triangles, 6M faces).
void BM_FindBadCells(benchmark::State& state) {
  const Mesh mesh = read_msh(gmsh_million_node_file());
  for (auto _ : state) {
    const BadCells bad = find_bad_cells(mesh);
    if (bad.count() != 0) state.SkipWithError("the square has bad cells");
  }
}
BENCHMARK(BM_FindBadCells)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(5)
    ->ReportAggregatesOnly(true)
    ->Iterations(1);

void BM_ReadMshAndBuild(benchmark::State& state) {
  const std::string path = gmsh_million_node_file();
  std::vector<LevelReport> report;
  for (auto _ : state) {
    const Mesh mesh = read_mesh(path);
    MultilevelGraph graph = build_multilevel_graph(mesh, BuildOptions{}, &report);
    benchmark::DoNotOptimize(graph.levels.data());
  }
  report_levels(state, report);
}
BENCHMARK(BM_ReadMshAndBuild)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(3)
    ->ReportAggregatesOnly(true)
    ->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
