// The bi-stride multilevel graph (thesis §4.2, DESIGN.md "Multilevel graph file").
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/graph.hpp"
#include "core/mesh.hpp"

namespace bsms {

enum class Seeding { kCloseCenter, kMinAve, kRandom };
std::string to_string(Seeding seeding);
Seeding parse_seeding(const std::string& name);  // "closecenter" | "minave" | "random"; InputError

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
  std::vector<GraphLevel> levels;  // levels[0] is the input mesh graph
  int num_levels() const { return static_cast<int>(levels.size()); }
};

// `--levels auto`: a candidate level k+1 is added only while all of these hold, so coarse levels
// neither turn dense (A² grows degrees: DESIGN.md's 243K-node mesh reaches 450K edges on 730
// nodes) nor tiny:
//   mean degree(k+1) <= kAutoMaxDegreeFactor * mean degree(0), and <= kAutoMaxMeanDegree;
//   the largest cluster of level k+1 has >= kAutoMinClusterNodes nodes;
//   N(k+1) < N(k)  (pooling still removes nodes).
constexpr double kAutoMaxDegreeFactor = 3.0;
constexpr double kAutoMaxMeanDegree = 64.0;
constexpr int64_t kAutoMinClusterNodes = 16;
constexpr int kAutoMaxLevels = 64;

struct BuildOptions {
  Seeding seeding = Seeding::kCloseCenter;
  int num_levels = 0;  // total levels including the input graph; 0 = auto (rule above)
  uint64_t seed = 0;   // Seeding::kRandom only
};

// Per-level figures of a build, for the CLI table and benchmarks.
struct LevelReport {
  int level = 0;
  int64_t nodes = 0;
  int64_t edges = 0;     // directed edges (both directions counted)
  int64_t clusters = 0;  // connected components of this level
  double mean_degree = 0.0;
  double milliseconds = 0.0;  // time to build this level from the previous one (0 for level 0)
};

// Builds the multilevel graph from a level-0 graph and its node positions [N, dim].
// Deterministic for given inputs and options, independent of the thread count.
MultilevelGraph build_multilevel_graph(const CsrGraph& graph, const RowMatrixXd& positions,
                                       const BuildOptions& options,
                                       std::vector<LevelReport>* report = nullptr);
// Same, from a mesh (level 0 = mesh_graph(mesh)).
MultilevelGraph build_multilevel_graph(const Mesh& mesh, const BuildOptions& options,
                                       std::vector<LevelReport>* report = nullptr);

// One coarsening step: level k+1 from level k (graph, positions and node weights set).
// `seed` is used by Seeding::kRandom only; `clusters_out` receives the number of clusters of `fine`.
GraphLevel coarsen_level(const GraphLevel& fine, Seeding seeding, uint64_t seed,
                         int64_t* clusters_out = nullptr);

double mean_degree(const CsrGraph& graph);  // directed edges / nodes (0 for an empty graph)

}  // namespace bsms
