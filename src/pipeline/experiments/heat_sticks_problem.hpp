// The heat-sticks problem of `bsms experiment heat-sticks` (thesis §4.4, Figure 4.6): sticks,
// their boundary conditions and exact solution, the two hierarchies compared, the measure of how
// much a hierarchy mixes the sticks, and the network. Training, testing and the report are in
// heat_sticks.hpp.
#pragma once

#include <torch/types.h>

#include <array>
#include <cstdint>
#include <vector>

#include "models/graph_tensors.hpp"
#include "models/networks.hpp"

namespace bsms {

// The level-1 grid cell of the proximity hierarchy, in units of dx: two nodes per cell on a stick.
constexpr double kProximityCellDx = 2.0;

// Nodes at most this many dx from the gap are the "near the gap" nodes of the metrics.
constexpr double kNearGapDx = 3.0;

// The two coarsenings compared.
enum class HierarchyKind { kBiStride, kProximity };

struct ModelSpec {
  HierarchyKind kind;
  const char* key;    // metrics.json and CSV name
  const char* label;  // plots and tables
};
constexpr std::array<ModelSpec, 2> kModels{{{HierarchyKind::kBiStride, "bistride", "bi-stride"},
                                            {HierarchyKind::kProximity, "proximity", "proximity"}}};

// The four test configurations, A then B from left to right; "DF" = Dirichlet end left, flux end
// right. The gap lies between the two middle letters.
struct Combo {
  const char* name;
  bool a_dirichlet_left, b_dirichlet_left;
};
constexpr std::array<Combo, 4> kCombos{{{"DF-DF", true, true},
                                        {"DF-FD", true, false},
                                        {"FD-DF", false, true},
                                        {"FD-FD", false, false}}};

// Most levels a stick of `nodes` nodes supports: the coarsest bi-stride level keeps >= 2 nodes.
int max_stick_levels(int64_t nodes);

// Boundary conditions of one stick: temperature t_dirichlet at one end (the left one when
// dirichlet_left), heat flux `flux` at the other.
struct StickBc {
  bool dirichlet_left = true;
  double t_dirichlet = 0.0;
  double flux = 0.0;
};

// Sticks of length 1 along x with `nodes` nodes each; stick s covers [starts[s], starts[s] + 1].
// Chain edges inside each stick (both directions), none between sticks.
struct Sticks {
  int64_t nodes = 0;           // per stick
  torch::Tensor positions;     // [S * nodes, 1] float32
  torch::Tensor edges;         // [E, 2] int64 (sender, receiver)
  std::vector<int64_t> stick;  // [S * nodes] stick of each node
  std::vector<double> x;       // [S * nodes] positions in double precision
  int64_t num_sticks() const { return nodes > 0 ? static_cast<int64_t>(stick.size()) / nodes : 0; }
  double dx() const { return 1.0 / static_cast<double>(nodes - 1); }
};
Sticks make_sticks(const std::vector<double>& starts, int64_t nodes);

// Node inputs [S * nodes, 3] = (is_dirichlet, is_flux, value), value = T_d at the Dirichlet node,
// q at the flux node, 0 elsewhere; one StickBc per stick.
torch::Tensor stick_inputs(const Sticks& sticks, const std::vector<StickBc>& bcs);
// Exact steady temperature [S * nodes, 1] float32, each stick on its own.
torch::Tensor stick_solution(const Sticks& sticks, const std::vector<StickBc>& bcs);

// The two hierarchies compared: bi-stride with CloseCenter seeding (preprocess/), and proximity
// with a level-1 cell of 2 dx (preprocess/proximity_pooling.hpp).
MultilevelTensors bistride_multilevel(const Sticks& sticks, int levels);
MultilevelTensors proximity_multilevel(const Sticks& sticks, int levels);

// Level-0 nodes of which sticks each node of each level aggregates (through the down transitions),
// as the range [lo, hi] of stick indices; a node with an empty row of D aggregates none.
// Per level: the nodes that aggregate more than one stick, and the edges whose two endpoints
// together aggregate more than one stick (edges that carry information across the gap).
struct StickMixing {
  std::vector<int64_t> mixed_nodes;        // [levels]
  std::vector<int64_t> cross_stick_edges;  // [levels]
};
StickMixing stick_mixing(const MultilevelTensors& graph, const std::vector<int64_t>& stick);

// The network of both models: BsmsGnn, 3 inputs, 1 output (T), 1-D positions.
GraphModelOptions heat_model_options(int levels, int64_t latent);

}  // namespace bsms
