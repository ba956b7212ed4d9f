// Training and inference step time and memory of BSMS-GNN and MeshGraphNets on structured
// triangulated rectangles: ~2.6K nodes with 5 levels and ~22K nodes with 7 levels, latent 128,
// inputs like CylinderFlow (velocity, node type; mesh-space edge offsets), 2 threads by default.
// "*_bf16" variants run the layers' matrix products in bfloat16 (MatmulPrecision).
// "scale/..." runs the same steps from ~300 to ~20K nodes on triangulated squares (2d) and
// tetrahedralised cubes (3d, Freudenthal's six tetrahedra per cube), levels chosen as training's
// `--levels auto` chooses them, for the cost per 1,000 nodes (counter ms_per_1k_nodes): a cost
// linear in the mesh keeps it flat.
//   build/bench/bench_models [--benchmark_filter=...]   (sets the bsms wait policy itself)
// BSMS_BENCH_THREADS sets the thread count. "concat" variants run the reference implementation's
// concat-then-Linear edge layer with the same parameters (models/layers.hpp, EdgeMlpMode).
// Counters: median_ms / min_ms per step (wall), cpu_ms = median process CPU time per step (all
// threads; robust to other load on the machine), peak_mb = peak RSS during the benchmark (process
// peak reset first), delta_mb = peak minus RSS before the model and graph were built.
#include <benchmark/benchmark.h>
#include <malloc.h>
#include <sys/resource.h>
#include <torch/torch.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/graph.hpp"
#include "core/runtime.hpp"
#include "models/fused_adam.hpp"
#include "models/graph_ops.hpp"
#include "models/networks.hpp"
#include "pipeline/graphs/multilevel_tensors.hpp"
#include "preprocess/multilevel_graph.hpp"

namespace {

using bsms::EdgeMlpMode;

struct Case {
  int64_t nx, ny;
  int levels;      // 0: as training's --levels auto (exact A², auto_levels)
  int64_t nz = 0;  // > 0: a 3-D box of tetrahedra
  int64_t nodes() const { return nx * ny * std::max<int64_t>(nz, 1); }
  int dim() const { return nz > 0 ? 3 : 2; }
};
const std::map<std::string, Case> kCases = {{"2.6K", {65, 40, 5}}, {"22K", {190, 116, 7}}};
const std::map<std::string, Case> kScaleCases = {
    {"2d/0.3K", {18, 18, 0}},
    {"2d/2K", {45, 45, 0}},
    {"2d/5K", {71, 71, 0}},
    {"2d/20K", {142, 142, 0}},
    {"3d/0.3K", {7, 7, 0, 7}},
    {"3d/2K", {13, 13, 0, 13}},
    {"3d/5K", {17, 17, 0, 17}},
    {"3d/20K", {27, 27, 0, 27}},
    // The same meshes at one level count: the hierarchy's depth held, what remains is the
    // implementation's own scaling.
    {"2d/2K-L4", {45, 45, 4}},
    {"2d/20K-L4", {142, 142, 4}},
    {"3d/2K-L3", {13, 13, 3, 13}},
    {"3d/20K-L3", {27, 27, 3, 27}}};

// Freudenthal's triangulation of an nx × ny × nz grid of nodes: each cube in six tetrahedra
// around its main diagonal, so node p links to p + d for the seven d in {0,1}³ \ {0}.
std::vector<int64_t> box_pairs(const Case& c, bsms::RowMatrixXd& positions) {
  auto id = [&](int64_t x, int64_t y, int64_t z) { return (z * c.ny + y) * c.nx + x; };
  std::vector<int64_t> pairs;
  positions.resize(c.nodes(), 3);
  for (int64_t z = 0; z < c.nz; ++z)
    for (int64_t y = 0; y < c.ny; ++y)
      for (int64_t x = 0; x < c.nx; ++x) {
        positions.row(id(x, y, z)) << 0.01 * static_cast<double>(x), 0.01 * static_cast<double>(y),
            0.01 * static_cast<double>(z);
        for (int d = 1; d < 8; ++d) {
          const int64_t dx = d & 1, dy = (d >> 1) & 1, dz = (d >> 2) & 1;
          if (x + dx < c.nx && y + dy < c.ny && z + dz < c.nz)
            pairs.insert(pairs.end(), {id(x, y, z), id(x + dx, y + dy, z + dz)});
        }
      }
  return pairs;
}

// Structured triangulated nx × ny rectangle (diagonals alternate direction by cell parity), or
// the box of tetrahedra when nz > 0.
bsms::MultilevelGraph make_graph(const Case& c, bsms::RowMatrixXd& positions) {
  bsms::BuildOptions options;
  options.num_levels = c.levels;
  if (c.levels == 0) options.thinning = bsms::Thinning::kOff;  // as training's auto_levels
  if (c.nz > 0) {
    const std::vector<int64_t> pairs = box_pairs(c, positions);
    return bsms::build_multilevel_graph(bsms::graph_from_pairs(c.nodes(), pairs), positions,
                                        options);
  }
  auto id = [&](int64_t x, int64_t y) { return y * c.nx + x; };
  std::vector<int64_t> pairs;
  positions.resize(c.nx * c.ny, 2);
  for (int64_t y = 0; y < c.ny; ++y) {
    for (int64_t x = 0; x < c.nx; ++x) {
      positions(id(x, y), 0) = 0.01 * static_cast<double>(x);
      positions(id(x, y), 1) = 0.01 * static_cast<double>(y);
      if (x + 1 < c.nx) pairs.insert(pairs.end(), {id(x, y), id(x + 1, y)});
      if (y + 1 < c.ny) pairs.insert(pairs.end(), {id(x, y), id(x, y + 1)});
      if (x + 1 < c.nx && y + 1 < c.ny) {
        if ((x + y) % 2 == 0) {
          pairs.insert(pairs.end(), {id(x, y), id(x + 1, y + 1)});
        } else {
          pairs.insert(pairs.end(), {id(x + 1, y), id(x, y + 1)});
        }
      }
    }
  }
  return bsms::build_multilevel_graph(bsms::graph_from_pairs(c.nx * c.ny, pairs), positions,
                                      options);
}

double rss_mb(const char* field) {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind(field, 0) == 0) return std::stod(line.substr(std::string(field).size())) / 1024;
  }
  return 0.0;
}

// Returns freed heap to the system and resets the peak RSS (VmHWM) to the current RSS.
void reset_peak_rss() {
  malloc_trim(0);
  std::ofstream("/proc/self/clear_refs") << "5";
}

// CPU time of the whole process (all threads, user + system), in ms.
double process_cpu_ms() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  auto ms = [](const timeval& t) { return t.tv_sec * 1e3 + t.tv_usec * 1e-3; };
  return ms(usage.ru_utime) + ms(usage.ru_stime);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

void run_case(benchmark::State& state, const Case& c, bool bsms_model, bool training,
              EdgeMlpMode mode, bool bf16 = false) {
  torch::manual_seed(0);
  bsms::set_matmul_precision(bf16 ? bsms::MatmulPrecision::kBFloat16
                                  : bsms::MatmulPrecision::kFloat32);
  reset_peak_rss();
  const double rss_before = rss_mb("VmRSS:");
  bsms::RowMatrixXd positions;
  auto graph = make_graph(c, positions);
  auto hierarchy = bsms::make_multilevel_tensors(graph, bsms_model ? 0 : 1);
  const int64_t n = hierarchy.num_nodes(0);
  const int dim = c.dim();
  bsms::GraphModelOptions o;
  o.input_size = dim + 1;
  o.output_size = dim;
  o.latent = 128;
  o.position_dims = {dim};
  o.num_levels = bsms_model ? graph.num_levels() : 1;
  o.message_passing_steps = 15;
  std::shared_ptr<bsms::GraphModel> model;
  if (bsms_model) {
    model = std::make_shared<bsms::BsmsGnn>(o);
  } else {
    model = std::make_shared<bsms::MeshGraphNets>(o);
  }
  model->set_edge_mlp_mode(mode);
  auto pos = torch::from_blob(positions.data(), {n, dim}, torch::kFloat64).to(torch::kFloat32);
  auto nodes = torch::randn({n, dim + 1});
  auto target = torch::randn({n, dim});
  // The trainer's optimizer; the "_concat" variants, done the original's way, step LibTorch's
  // own Adam (one op per update term, as PyTorch's on CPU).
  std::unique_ptr<torch::optim::Adam> adam;
  if (mode == EdgeMlpMode::kConcat)
    adam =
        std::make_unique<torch::optim::Adam>(model->parameters(), torch::optim::AdamOptions(1e-4));
  else
    adam = std::make_unique<bsms::FusedAdam>(model->parameters(), torch::optim::AdamOptions(1e-4));
  auto step = [&] {
    if (training) {
      adam->zero_grad();
      auto loss = (model->forward(nodes, {pos}, hierarchy) - target).square().mean();
      loss.backward();
      adam->step();
    } else {
      torch::InferenceMode guard;
      auto out = model->forward(nodes, {pos}, hierarchy);
      benchmark::DoNotOptimize(out.data_ptr<float>());
    }
  };
  step();  // warm-up: allocator, Adam state
  std::vector<double> ms, cpu_ms;
  for (auto _ : state) {
    const double cpu_start = process_cpu_ms();
    bsms::Stopwatch clock;
    step();
    ms.push_back(clock.milliseconds());
    cpu_ms.push_back(process_cpu_ms() - cpu_start);
  }
  int64_t edges = 0;
  for (const auto& sets : hierarchy.edge_sets) edges += sets[0].num_edges();
  state.counters["median_ms"] = median(ms);
  state.counters["min_ms"] = *std::min_element(ms.begin(), ms.end());
  state.counters["cpu_ms"] = median(cpu_ms);
  state.counters["peak_mb"] = rss_mb("VmHWM:");
  state.counters["delta_mb"] = rss_mb("VmHWM:") - rss_before;
  state.counters["nodes"] = static_cast<double>(n);
  state.counters["levels"] = o.num_levels;
  state.counters["ms_per_1k_nodes"] = median(ms) * 1000.0 / static_cast<double>(n);
  state.counters["edges_all_levels"] = static_cast<double>(edges);
  state.counters["threads"] = torch::get_num_threads();
  bsms::set_matmul_precision(bsms::MatmulPrecision::kFloat32);
}

void register_all() {
  struct Variant {
    const char* name;
    bool bsms_model;
    EdgeMlpMode mode;
  };
  const Variant variants[] = {{"bsms", true, EdgeMlpMode::kProjection},
                              {"bsms_concat", true, EdgeMlpMode::kConcat},
                              {"mgn", false, EdgeMlpMode::kProjection},
                              {"mgn_concat", false, EdgeMlpMode::kConcat}};
  for (const auto& [case_name, c] : kCases) {
    for (const auto& v : variants) {
      for (bool training : {true, false}) {
        const std::string name =
            std::string(training ? "train/" : "infer/") + v.name + "/" + case_name;
        const bool big = c.nx * c.ny > 10000;
        const int iterations = big ? (training ? 3 : 5) : (training ? 10 : 20);
        const Case cc = c;
        const bool bsms_model = v.bsms_model;
        const EdgeMlpMode mode = v.mode;
        benchmark::RegisterBenchmark(name.c_str(),
                                     [cc, bsms_model, training, mode](benchmark::State& state) {
                                       run_case(state, cc, bsms_model, training, mode);
                                     })
            ->Iterations(iterations)
            ->Unit(benchmark::kMillisecond);
      }
    }
  }
  // The bfloat16 products (models/graph_ops.hpp MatmulPrecision) beside float32 at 2.6K nodes.
  for (bool bsms_model : {true, false}) {
    for (bool training : {true, false}) {
      const std::string name = std::string(training ? "train/" : "infer/") +
                               (bsms_model ? "bsms" : "mgn") + "_bf16/2.6K";
      const Case cc = kCases.at("2.6K");
      benchmark::RegisterBenchmark(name.c_str(),
                                   [cc, bsms_model, training](benchmark::State& state) {
                                     run_case(state, cc, bsms_model, training,
                                              EdgeMlpMode::kProjection, true);
                                   })
          ->Iterations(training ? 10 : 20)
          ->Unit(benchmark::kMillisecond);
    }
  }
  for (const auto& [case_name, c] : kScaleCases) {
    for (const auto& v : variants) {
      if (v.mode != EdgeMlpMode::kProjection) continue;
      for (bool training : {true, false}) {
        const std::string name =
            std::string("scale/") + (training ? "train/" : "infer/") + v.name + "/" + case_name;
        const int iterations = c.nodes() > 10000 ? (training ? 3 : 5) : (training ? 10 : 20);
        const Case cc = c;
        const bool bsms_model = v.bsms_model;
        benchmark::RegisterBenchmark(name.c_str(),
                                     [cc, bsms_model, training](benchmark::State& state) {
                                       run_case(state, cc, bsms_model, training,
                                                EdgeMlpMode::kProjection);
                                     })
            ->Iterations(iterations)
            ->Unit(benchmark::kMillisecond);
      }
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  bsms::ensure_process_environment(argv);  // as the bsms executable does (core/runtime.hpp)
  bsms::tune_allocator();                  // as the bsms executable does
  const char* env_threads = std::getenv("BSMS_BENCH_THREADS");
  const int threads = bsms::set_num_threads(env_threads ? std::atoi(env_threads) : 2);
  bsms::configure_threads(threads);
  register_all();
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
