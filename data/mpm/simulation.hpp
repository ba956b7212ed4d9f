// Running a scene end to end and writing its frames (docs/design.md "Simulation frames"):
// DIR/frames.h5, DIR/frames.xdmf (XDMF 3 temporal collection of Polyvertex grids for ParaView,
// reading DIR/frames.xdmf.h5: per-frame views of frames.h5) and DIR/scene.json (the resolved
// scene).
#pragma once

#include <cstdint>
#include <string>

#include "data/mpm/scene_config.hpp"

namespace bsms::mpm {

struct SimulationSummary {
  int64_t steps = 0;
  int32_t particles = 0;
  int32_t frames = 0;
  double wall_s = 0.0;  // stepping time, s
  double particle_steps_per_s = 0.0;
  double energy_initial = 0.0, energy_final = 0.0;  // kinetic + elastic + gravitational, J
  double energy_drift = 0.0;    // |E_final − E_initial| / max(|E_initial|, K_max)
  double momentum_drift = 0.0;  // |p_final − p_initial| / max over frames of Σ m |v|
  std::string summary_line() const;
};

// Runs `scene` (threads as set by set_num_threads) and writes both files atomically: a failed
// step (NumericalError) leaves no frames file behind. `progress` draws a progress bar on stderr.
SimulationSummary simulate_scene(const Scene& scene, const std::string& out_dir, bool progress);

}  // namespace bsms::mpm
