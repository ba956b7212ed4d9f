// Running a scene end to end and writing its frames (docs/design.md "Simulation frames"):
// DIR/frames.h5, DIR/frames.xdmf (XDMF 3 temporal collection of Polyvertex grids for ParaView,
// reading DIR/frames.xdmf.h5: per-frame views of frames.h5) and DIR/scene.json (the resolved
// scene).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

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

// A scene's recorded frames in memory, as frames.h5 stores them (docs/design.md "Simulation
// frames"). Fields not among the scene's output fields stay empty.
struct SimulationFrames {
  int dim = 0;
  int64_t particles = 0;
  bool has_velocity = false, has_stress = false, has_plastic_strain = false;
  std::vector<double> time;                   // [T] s
  std::vector<float> position, velocity;      // [T, P, dim] m, m/s
  std::vector<float> stress, plastic_strain;  // [T, P] von Mises stress (Pa), plastic strain
  std::vector<double> energy;                 // [T, 3] kinetic, elastic, gravitational (J)
  std::vector<double> momentum;               // [T, dim]
  std::vector<double> angular_momentum;       // [T, angular_width]
  int angular_width = 0;                      // 1 in 2-D, 3 in 3-D
  std::vector<double> mass, volume0;          // [P] kg, m^dim
  int64_t num_frames() const { return static_cast<int64_t>(time.size()); }
};

// Told after each recorded frame but the first: frames done, frames to do, solver steps so far.
using SimulationProgress = std::function<void(int64_t done, int64_t total, int64_t steps)>;

// Runs `scene` (threads as set by set_num_threads) into `frames`. NumericalError on a failed step.
SimulationSummary solve_scene(const Scene& scene, SimulationFrames& frames,
                              const SimulationProgress& progress = {});

// Writes frames.h5, frames.xdmf (+ its views file) and scene.json of a solved scene into
// `out_dir`, each atomically.
void write_simulation(const Scene& scene, const SimulationFrames& frames,
                      const std::string& out_dir);

// solve_scene + write_simulation: runs `scene` and writes both files atomically: a failed
// step (NumericalError) leaves no frames file behind. `progress` draws a progress bar on stderr.
SimulationSummary simulate_scene(const Scene& scene, const std::string& out_dir, bool progress);

}  // namespace bsms::mpm
