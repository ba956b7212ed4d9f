// MPM throughput: particle-steps per second of UMLS (2D triangles, 3D tetrahedra) next to the
// quadratic B-spline solver on a regular lattice, same scene, same particles.
// Run: build/bench_mpm --benchmark_counters_tabular=true   (threads: second argument)
#include <benchmark/benchmark.h>

#include <string>

#include "core/error.hpp"
#include "core/runtime.hpp"
#include "data/mpm/scene_builder.hpp"

namespace {

using bsms::Json;
using namespace bsms::mpm;

// Two elastic blocks colliding in a box with slip walls (2D: 0.02 m elements, 0.005 m particle
// spacing; 3D: 0.05 m elements, 0.025 m spacing).
Json bench_scene(int dim, const std::string& kernel) {
  const bool d3 = dim == 3;
  Json j = {
      {"dim", dim},
      {"background",
       {{"type", "box"},
        {"min", d3 ? Json{0.0, 0.0, 0.0} : Json{0.0, 0.0}},
        {"max", d3 ? Json{1.0, 1.0, 1.0} : Json{1.0, 1.0}},
        {"element_size", d3 ? 0.05 : 0.02},
        {"structured", true}}},
      {"bodies", Json::array()},
      {"boundaries", Json::array()},
      {"solver", {{"kernel", kernel}, {"transfer", "apic"}, {"end_time", 1.0}}},
  };
  for (const char* side : {"left", "right", "bottom", "top", "back", "front"})
    if (d3 || (std::string(side) != "back" && std::string(side) != "front"))
      j["boundaries"].push_back({{"group", side}, {"type", "slip"}});
  const double s = d3 ? 0.025 : 0.005;
  for (int b = 0; b < 2; ++b) {
    const double lo = b == 0 ? 0.15 : 0.55, hi = lo + 0.3;
    Json body = {{"shape", {{"type", "box"}, {"min", Json::array()}, {"max", Json::array()}}},
                 {"spacing", s},
                 {"sampling", "cell_centres"},
                 {"material",
                  {{"model", "neo_hookean"},
                   {"youngs_modulus", 1e4},
                   {"poisson_ratio", 0.3},
                   {"density", 1e3}}},
                 {"velocity", {{"type", "uniform"}, {"value", Json::array()}}}};
    for (int a = 0; a < dim; ++a) {
      body["shape"]["min"].push_back(a == 0 ? lo : 0.35);
      body["shape"]["max"].push_back(a == 0 ? hi : 0.65);
      body["velocity"]["value"].push_back(a == 0 ? (b == 0 ? 0.5 : -0.5) : 0.0);
    }
    j["bodies"].push_back(body);
  }
  return j;
}

template <int Dim>
void run(benchmark::State& state, const std::string& kernel) {
  bsms::set_num_threads(static_cast<int>(state.range(0)));
  const Scene scene = parse_scene(bench_scene(Dim, kernel), "bench_mpm");
  BuiltScene<Dim> b = build_scene<Dim>(scene);
  const int32_t particles = b.particles.size();
  MpmSolver<Dim> solver(std::move(b.background), std::move(b.materials), std::move(b.particles),
                        std::move(b.constraints), b.settings);
  const double dt = solver.stable_dt();
  try {
    solver.step(dt);  // warm-up: buffers sized, walk hints set
    for (auto _ : state) solver.step(dt);
  } catch (const bsms::NumericalError& e) {
    state.SkipWithError(e.what());  // linear FEM kernels may invert particles (cell crossing)
    return;
  }
  state.SetItemsProcessed(state.iterations() * particles);
  state.counters["particles"] = particles;
  state.counters["threads"] = static_cast<double>(state.range(0));
  state.counters["particle_steps_per_s"] = benchmark::Counter(
      static_cast<double>(state.iterations()) * particles, benchmark::Counter::kIsRate);
}

void BM_Mpm2D_Umls(benchmark::State& s) {
  run<2>(s, "umls");
}
void BM_Mpm2D_Bspline(benchmark::State& s) {
  run<2>(s, "bspline");
}
void BM_Mpm2D_LinearFem(benchmark::State& s) {
  run<2>(s, "linear_fem");
}
void BM_Mpm3D_Umls(benchmark::State& s) {
  run<3>(s, "umls");
}
void BM_Mpm3D_Bspline(benchmark::State& s) {
  run<3>(s, "bspline");
}

}  // namespace

BENCHMARK(BM_Mpm2D_Umls)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Mpm2D_Bspline)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Mpm2D_LinearFem)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Mpm3D_Umls)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Mpm3D_Bspline)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK_MAIN();
