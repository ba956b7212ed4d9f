// One trajectory of a scene family: the draw of a global index (Rng(trajectory_seed(...))), its
// scene parsed, built and solved single-threaded with UMLS-MPM, recorded as a dataset Trajectory
// (mesh, node types from the family's fixed planes and actuator bodies, bodies, fields).
// Unstable draws (NumericalError) are replaced by the next attempt. generator.hpp runs many of
// these into a crash-safe dataset.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "data/dataset/dataset.hpp"
#include "data/generate/family.hpp"

namespace bsms::generate {

// A change to the state between recorded frames, for experiments on the solver's own
// predictability: called after frame `frame` is recorded and before the solve goes on to frame + 1,
// with the particles' (= mesh nodes') positions x and velocities v, flat [P * dim] in m and m/s.
// The velocities it leaves in v are the solver's from then on (positions are read only).
using FrameHook =
    std::function<void(int frame, const std::vector<double>& x, std::vector<double>& v)>;

// Draw `attempt` of global trajectory `index`, solved single-threaded: mesh, node types, bodies,
// fields [T, N, width]. Throws NumericalError when the solve is unstable. `hook`, when set, may
// perturb the velocities at each recorded frame (see FrameHook); without it the solve is the one
// bsms generate stores.
Trajectory solve_draw(const FamilyConfig& family, int64_t seed, int64_t index, int attempt,
                      const std::string& work_prefix, const FrameHook& hook = {});

// The draw a generated trajectory came from: its parameters' run seed, global index and attempt
// (solve_draw(family, run_seed, index, attempt, ...) solves it again).
struct StoredDraw {
  int64_t run_seed = 0, index = 0;
  int attempt = 0;
};
// Trajectory `t` of a bsms generate dataset, checked to come from family `family`; InputError
// naming the file and trajectory when its parameters lack the draw or name another family.
StoredDraw stored_draw(const Dataset& data, int64_t t, const std::string& family);

// One trajectory: draws the scene of global index `index` (redrawing unstable draws), solves it
// single-threaded and returns it with its node types, bodies and fields. `work_prefix` names
// scratch files (union geometry). `on_redraw` is told about each unstable draw.
Trajectory generate_trajectory(const FamilyConfig& family, int64_t seed, int64_t index,
                               int max_attempts, const std::string& work_prefix,
                               const std::function<void(const std::string&)>& on_redraw = {});

}  // namespace bsms::generate
