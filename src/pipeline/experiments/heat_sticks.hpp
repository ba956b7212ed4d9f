// `bsms experiment heat-sticks`: the failure case of coarsening by spatial proximity (thesis §4.4,
// Figure 4.6). 1-D steady heat conduction on sticks of length 1 and conductivity 1: temperature
// T_d at one end, heat flux q at the other, exact solution T(s) = T_d + q s with s the distance
// from the Dirichlet end. The same BsmsGnn network is trained on single sticks with the bi-stride
// hierarchy and with a proximity (grid) hierarchy, then tested on two sticks placed head to tail
// with a small gap: no heat crosses the gap, so each stick keeps its own solution.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/config.hpp"
#include "pipeline/experiments/heat_sticks_problem.hpp"

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

// Trains both models with the trainer's loop and schedule (pipeline/fit), tests them and writes
// to options.out: metrics.json, profiles.csv, heat_sticks.md and plots/heat_sticks.png (the plot
// is left out, and the markdown says so, when gnuplot is not installed). Progress bars go to
// stderr. Returns the metrics.
Json run_heat_sticks(const HeatSticksOptions& options);

// The report section (heat_sticks.md) from run_heat_sticks' metrics: setup, the table of both
// models and the reading; `near_gap_nodes` test nodes within kNearGapDx of the gap; `plotted`:
// whether plots/heat_sticks.png was drawn.
std::string heat_sticks_markdown(const HeatSticksOptions& options, const Json& metrics,
                                 int64_t near_gap_nodes, int threads, bool plotted);

}  // namespace bsms
