// `bsms experiment heat-sticks`: the failure case of coarsening by spatial proximity (thesis §4.4,
// Figure 4.6). 1-D steady heat conduction on sticks of length 1 and conductivity 1: temperature
// T_d at one end, heat flux q at the other, exact solution T(s) = T_d + q s with s the distance
// from the Dirichlet end. The same BsmsGnn network is trained on single sticks with the bi-stride
// hierarchy and with a proximity (grid) hierarchy, then tested on two sticks placed head to tail
// with a small gap: no heat crosses the gap, so each stick keeps its own solution.
#pragma once

#include <torch/types.h>

#include <cstdint>
#include <string>
#include <vector>

#include "core/config.hpp"
#include "models/graph_tensors.hpp"
#include "models/networks.hpp"

namespace bsms {

struct HeatSticksOptions {
  std::string out;         // output folder
  int64_t steps = 3000;    // training steps per model
  int64_t nodes = 33;      // nodes per stick (spacing dx = 1 / (nodes - 1))
  int levels = 5;          // levels of both hierarchies, the input graph included
  double gap = 0.25;       // gap between the test sticks, in units of dx
  int64_t latent = 64;     // MLP width
  int64_t batch = 8;       // sticks per training step
  int64_t test_draws = 8;  // boundary-condition draws per orientation combination
  double lr = 1e-3;        // Adam learning rate, decayed exponentially ...
  double lr_final = 1e-5;  // ... to this value at the last step
  uint64_t seed = 0;       // model initialisation, training draws and test draws
  int threads = 0;         // <= 0: all hardware threads
};

// InputError naming the option as the CLI spells it (--steps, --levels, ...) and what is expected.
void validate(const HeatSticksOptions& options);

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
// with a level-1 cell of 2 dx (models/proximity_hierarchy.hpp).
GraphHierarchy bistride_hierarchy(const Sticks& sticks, int levels);
GraphHierarchy proximity_hierarchy(const Sticks& sticks, int levels);

// Level-0 nodes of which sticks each node of each level aggregates (through the down transitions),
// as the range [lo, hi] of stick indices; a node with an empty row of D aggregates none.
// Per level: the nodes that aggregate more than one stick, and the edges whose two endpoints
// together aggregate more than one stick (edges that carry information across the gap).
struct StickMixing {
  std::vector<int64_t> mixed_nodes;        // [levels]
  std::vector<int64_t> cross_stick_edges;  // [levels]
};
StickMixing stick_mixing(const GraphHierarchy& graph, const std::vector<int64_t>& stick);

// The network of both models: BsmsGnn, 3 inputs, 1 output (T), 1-D positions.
GraphModelOptions heat_model_options(int levels, int64_t latent);

// Trains both models with the trainer's loop and schedule (pipeline/fit), tests them and writes
// to options.out: metrics.json, profiles.csv, heat_sticks.md and plots/heat_sticks.png (the plot
// is left out, and the markdown says so, when gnuplot is not installed). Progress bars go to
// stderr. Returns the metrics.
Json run_heat_sticks(const HeatSticksOptions& options);

}  // namespace bsms
