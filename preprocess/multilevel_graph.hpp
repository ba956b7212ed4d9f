// The bi-stride multilevel graph (thesis §4.2, docs/design.md "Multilevel graph file").
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/graph.hpp"
#include "core/mesh.hpp"

namespace bsms {

enum class Seeding { kCloseCenter, kMinAve, kRandom };
// Every seeding, in the order tables and help texts list them.
constexpr std::array<Seeding, 3> kAllSeedings{Seeding::kMinAve, Seeding::kCloseCenter,
                                              Seeding::kRandom};
std::string to_string(Seeding seeding);          // the name of files, configs and the CLI
Seeding parse_seeding(const std::string& name);  // "closecenter" | "minave" | "random"; InputError
std::vector<std::string> seeding_names();        // to_string of kAllSeedings

struct GraphLevel {
  CsrGraph graph;                  // symmetric adjacency among this level's nodes, no self loops
  std::vector<int64_t> pooled;     // (k >= 1) indices into level k-1 kept at level k, ascending
  std::vector<float> down_weight;  // (k >= 1) weight of each level-(k-1) edge, CSR edge order
  // In memory only (not in the file): positions [N_k, dim] of the kept input nodes, and the
  // accumulated node weight w [N_k] of §4.3.2 (1 at level 0).
  RowMatrixXd positions;
  std::vector<double> node_weight;
  int64_t num_nodes() const { return graph.num_nodes; }
};

struct MultilevelGraph {
  Seeding seeding = Seeding::kCloseCenter;
  bool thinned = false;  // coarse levels thinned (edge_thinning.hpp) rather than exact A²
  std::vector<GraphLevel> levels;  // levels[0] is the input mesh graph
  int num_levels() const { return static_cast<int>(levels.size()); }
};

// Coarse-level thinning (preprocess/edge_thinning.hpp): kAuto thins with `--levels auto` and
// keeps the exact A² of docs/design.md when a level count is given; kOn / kOff force it.
enum class Thinning { kAuto, kOn, kOff };
std::string to_string(Thinning thinning);
Thinning parse_thinning(const std::string& name);  // "auto" | "on" | "off"; InputError

// `--levels auto` (thinned levels): a candidate level k+1 is added only while all of these hold,
// so the hierarchy costs a bounded multiple of its mesh and stops once a level is small enough to
// give every cluster global reach:
//   N(k+1) < N(k)                                    pooling still removes nodes;
//   largest cluster of level k+1 >= kAutoMinClusterNodes nodes;
//   E(1) + ... + E(k+1) <= kAutoMaxEdgesFactor * E(0)  all coarse levels together cost at most
//                                                    this many mesh-level message passings;
//   E(k+1) <= kAutoMaxDensity * sum_c n_c (n_c - 1)  at most this fraction of the node pairs
//                                                    inside clusters are joined.
// Without thinning (positions missing, or Thinning::kOff with auto levels) the edge bound applies
// to each level alone, as before thinning existed: exact A² roughly doubles the mean degree per
// level on 2D meshes (a 1M-node plate: 9 levels, 5.8x the edges of level 0), so a total bound
// would stop after one or two levels.
constexpr int64_t kAutoMinClusterNodes = 16;
constexpr double kAutoMaxEdgesFactor = 2.0;
constexpr double kAutoMaxLevelEdgesFactor = 2.0;  // per level, exact A²
constexpr double kAutoMaxDensity = 0.25;
constexpr int kAutoMaxLevels = 64;

// True when `candidate` (a coarser level of a graph whose level 0 has `level0_edges` edges, built
// from a level of `previous_nodes` nodes, with `coarse_edges` edges on the coarse levels already
// accepted) passes the `--levels auto` rule above; `thinned` selects the total or per-level edge
// bound.
bool auto_accepts_level(const CsrGraph& candidate, int64_t previous_nodes, int64_t level0_edges,
                        int64_t coarse_edges, bool thinned);

struct BuildOptions {
  Seeding seeding = Seeding::kCloseCenter;
  int num_levels = 0;     // total levels including the input graph; 0 = auto (rule above)
  uint64_t rng_seed = 0;  // Seeding::kRandom only
  Thinning thinning = Thinning::kAuto;
};

// Per-level figures of a build, for the CLI table and benchmarks.
struct LevelReport {
  int level = 0;
  int64_t nodes = 0;
  int64_t edges = 0;     // directed edges (both directions counted)
  int64_t clusters = 0;  // connected components of this level
  double mean_degree = 0.0;
  // Time to build this level from the previous one; level 0: building the mesh graph (0 when
  // the graph was given).
  double milliseconds = 0.0;
};

// Builds the multilevel graph from a level-0 graph and its node positions [N, dim].
// Deterministic for given inputs and options, independent of the thread count.
MultilevelGraph build_multilevel_graph(CsrGraph graph, const RowMatrixXd& positions,
                                       const BuildOptions& options,
                                       std::vector<LevelReport>* report = nullptr);
// Same, from a mesh (level 0 = mesh_graph(mesh)).
MultilevelGraph build_multilevel_graph(const Mesh& mesh, const BuildOptions& options,
                                       std::vector<LevelReport>* report = nullptr);

// One coarsening step: level k+1 from level k (graph, positions and node weights set).
// `rng_seed` is used by Seeding::kRandom only; `thin`: thin the coarse graph (needs positions);
// `clusters_out` receives the number of clusters of `fine`.
GraphLevel coarsen_level(const GraphLevel& fine, Seeding seeding, uint64_t rng_seed,
                         bool thin = false, int64_t* clusters_out = nullptr);

double mean_degree(const CsrGraph& graph);  // directed edges / nodes (0 for an empty graph)

}  // namespace bsms
