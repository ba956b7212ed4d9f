// Physical validity of one rollout frame (core/physical_validity.hpp): overlap between bodies,
// nodes inside other bodies and outside the walls. Scenes of ~3,000 nodes: 2x2x2 cubes of
// 6^3 x 6 tetrahedra (2,744 nodes, 10,368 cells) or 4x3 squares of 15^2 x 2 triangles (3,072
// nodes, 5,400 cells), jittered and pressed 5 % into their neighbours; "stretched": one node
// flung 20 sizes away (large cells, a coarser grid).
// Projection (core/physical_projection.hpp) of the same pressed scenes back apart, walls, cells and
// contact, rest = the bodies 1.05 apart; "Apart": a frame with nothing to correct (the cost of
// checking every constraint once).
// Run: build/bench/bench_validity --benchmark_repetitions=10 --benchmark_report_aggregates_only
#include <benchmark/benchmark.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <vector>

#include "core/mesh.hpp"
#include "core/physical_projection.hpp"
#include "core/physical_validity.hpp"

namespace {

using bsms::BoxWalls;
using bsms::FrameValidity;
using bsms::PhysicalValidity;

struct Frame {
  int dim = 3;
  std::vector<float> x;
  std::vector<int32_t> cells, body;
};

// `per_axis` bodies along each axis, each a unit square / cube of n^dim squares / cubes split
// into simplices, placed 0.95 apart.
Frame pressed_bodies(int dim, const std::vector<int>& per_axis, int n, bool stretched,
                     float pitch = 0.95f) {
  Frame f;
  f.dim = dim;
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> jitter(-0.01f, 0.01f);
  const int cz = dim == 3 ? per_axis[2] : 1;
  int32_t id = 0;
  for (int bz = 0; bz < cz; ++bz)
    for (int by = 0; by < per_axis[1]; ++by)
      for (int bx = 0; bx < per_axis[0]; ++bx, ++id) {
        const int32_t offset = static_cast<int32_t>(f.body.size());
        const int nz = dim == 3 ? n : 0;
        auto index = [&](int i, int j, int k) {
          return offset + static_cast<int32_t>((k * (n + 1) + j) * (n + 1) + i);
        };
        for (int k = 0; k <= nz; ++k)
          for (int j = 0; j <= n; ++j)
            for (int i = 0; i <= n; ++i) {
              f.x.push_back(pitch * static_cast<float>(bx) + static_cast<float>(i) / n +
                            jitter(rng));
              f.x.push_back(pitch * static_cast<float>(by) + static_cast<float>(j) / n +
                            jitter(rng));
              if (dim == 3)
                f.x.push_back(pitch * static_cast<float>(bz) + static_cast<float>(k) / n +
                              jitter(rng));
              f.body.push_back(id);
            }
        const int axes[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
        for (int k = 0; k < std::max(nz, 1); ++k)
          for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
              if (dim == 2) {
                const int32_t a = index(i, j, 0), b = index(i + 1, j, 0),
                              c = index(i + 1, j + 1, 0), d = index(i, j + 1, 0);
                f.cells.insert(f.cells.end(), {a, b, c, a, c, d});
                continue;
              }
              for (const auto& order : axes) {
                int at[3] = {i, j, k};
                f.cells.push_back(index(at[0], at[1], at[2]));
                for (int s = 0; s < 3; ++s) {
                  ++at[order[s]];
                  f.cells.push_back(index(at[0], at[1], at[2]));
                }
              }
            }
      }
  if (stretched) f.x[f.x.size() / 2] += 20.0f;
  return f;
}

// 2x2x2 unit cubes meshed by gmsh (unstructured tetrahedra, element size 0.16: 375 nodes and
// 1,306 cells each), placed `pitch` apart.
Frame gmsh_cubes(float pitch) {
  const std::filesystem::path geo =
      std::filesystem::temp_directory_path() / "bench_validity_cube.geo";
  std::ofstream(geo)
      << "SetFactory(\"OpenCASCADE\");\nBox(1) = {0, 0, 0, 1, 1, 1};\n"
         "Mesh.CharacteristicLengthMax = 0.16;\nMesh.CharacteristicLengthMin = 0.16;\n"
         "Physical Volume(\"body\") = {1};\n";
  const bsms::Mesh cube = bsms::read_mesh(geo.string());
  std::filesystem::remove(geo);
  Frame f;
  f.dim = 3;
  int32_t id = 0;
  for (int bz = 0; bz < 2; ++bz)
    for (int by = 0; by < 2; ++by)
      for (int bx = 0; bx < 2; ++bx, ++id) {
        const int32_t offset = static_cast<int32_t>(f.body.size());
        for (int64_t i = 0; i < cube.num_nodes(); ++i) {
          f.x.push_back(pitch * static_cast<float>(bx) + static_cast<float>(cube.points(i, 0)));
          f.x.push_back(pitch * static_cast<float>(by) + static_cast<float>(cube.points(i, 1)));
          f.x.push_back(pitch * static_cast<float>(bz) + static_cast<float>(cube.points(i, 2)));
          f.body.push_back(id);
        }
        for (int64_t c = 0; c < cube.num_cells(); ++c)
          for (int j = 0; j < 4; ++j)
            f.cells.push_back(offset + static_cast<int32_t>(cube.cells(c, j)));
      }
  return f;
}

void run(benchmark::State& state, const Frame& f) {
  const int64_t nodes = static_cast<int64_t>(f.body.size());
  std::vector<double> lo(static_cast<size_t>(f.dim), 0.0), hi(static_cast<size_t>(f.dim), 2.0);
  const PhysicalValidity validity(f.dim, f.cells, f.body, nodes, BoxWalls{lo, hi});
  FrameValidity v;
  for (auto _ : state) {
    v = validity.measure(f.x.data());
    benchmark::DoNotOptimize(v);
  }
  state.counters["nodes"] = static_cast<double>(nodes);
  state.counters["cells"] = static_cast<double>(validity.num_cells());
  state.counters["pairs"] = static_cast<double>(v.candidate_pairs);
  state.counters["overlap"] = v.overlap_fraction();
  state.counters["inside"] = static_cast<double>(v.nodes_in_other_body);
}

void BM_Validity3D(benchmark::State& state) {
  run(state, pressed_bodies(3, {2, 2, 2}, 6, false));
}
void BM_Validity3DTouching(benchmark::State& state) {
  run(state, pressed_bodies(3, {2, 2, 2}, 6, false, 0.995f));
}
void BM_Validity3DApart(benchmark::State& state) {
  run(state, pressed_bodies(3, {2, 2, 2}, 6, false, 1.05f));
}
void BM_Validity3DGmsh(benchmark::State& state) {
  run(state, gmsh_cubes(static_cast<float>(state.range(0)) / 1000));
}
void BM_Validity3DStretched(benchmark::State& state) {
  run(state, pressed_bodies(3, {2, 2, 2}, 6, true));
}
void BM_Validity2D(benchmark::State& state) {
  run(state, pressed_bodies(2, {4, 3}, 15, false));
}

void project(benchmark::State& state, int dim, const std::vector<int>& per_axis, int n,
             float pitch) {
  const Frame rest = pressed_bodies(dim, per_axis, n, false, 1.05f);
  const Frame f = pressed_bodies(dim, per_axis, n, false, pitch);
  const int64_t nodes = static_cast<int64_t>(f.body.size());
  const bsms::PhysicalProjection projection(
      dim, f.cells, f.body, nodes, rest.x.data(),
      BoxWalls{std::vector<double>(static_cast<size_t>(dim), 0.0),
               std::vector<double>(static_cast<size_t>(dim), 5.0)},
      bsms::parse_projection("all"));
  bsms::ProjectionCounts counts;
  std::vector<float> x;
  for (auto _ : state) {
    x = f.x;
    counts = projection.project(x.data());
    benchmark::DoNotOptimize(x.data());
  }
  state.counters["nodes"] = static_cast<double>(nodes);
  state.counters["passes"] = counts.passes;
  state.counters["pushed"] = static_cast<double>(counts.nodes_pushed_out);
  state.counters["restored"] = static_cast<double>(counts.cells_restored);
  state.counters["clamped"] = static_cast<double>(counts.nodes_clamped);
  state.counters["converged"] = counts.converged;
}
void BM_Projection3D(benchmark::State& state) {
  project(state, 3, {2, 2, 2}, 6, 0.95f);
}
void BM_Projection3DApart(benchmark::State& state) {
  project(state, 3, {2, 2, 2}, 6, 1.05f);
}
void BM_Projection2D(benchmark::State& state) {
  project(state, 2, {4, 3}, 15, 0.95f);
}
void BM_Projection2DApart(benchmark::State& state) {
  project(state, 2, {4, 3}, 15, 1.05f);
}

BENCHMARK(BM_Validity3D)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Validity3DTouching)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Validity3DApart)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Validity3DGmsh)->Arg(950)->Arg(995)->Arg(1050)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Validity3DStretched)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Validity2D)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Projection3D)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Projection3DApart)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Projection2D)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Projection2DApart)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
