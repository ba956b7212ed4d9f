// The size of a scene's work, estimated from its JSON alone (no meshing), so that a typo such as
// `spacing` 1e-7 m for 1e-2 is refused in a millisecond instead of meshing until killed.
// Unstructured gmsh meshes are estimated from the measure over the element size^dim (node
// density of equilateral simplices); structured boxes and lattices are counted exactly; mesh
// files count 0 here (the file bounds them). Steps: end_time / dt, or with a CFL step the
// material wave speed plus the largest initial speed over cfl times the element size.
#pragma once

#include "data/mpm/scene_config.hpp"

namespace bsms::mpm {

struct SceneEstimate {
  double particles = 0.0;  // material points, all bodies
  double nodes = 0.0;      // background nodes
  double steps = 0.0;      // time steps to end_time (0 when unknown: a mesh-file background)
  double bytes = 0.0;      // peak memory: particles, background, stencils, kernel slots, frames
  // Largest body (index) by particles, for the message's key.
  int largest_body = 0;
};
SceneEstimate estimate_scene(const Scene& scene);

// Limits of estimate_scene's figures: beyond them build_scene refuses the scene with an
// InputError naming the file, the key, the estimate and the limit (exit 2 in the CLI).
constexpr double kMaxParticles = 5e7;
constexpr double kMaxBackgroundNodes = 5e7;
constexpr double kMaxSteps = 1e9;
constexpr double kMaxNodeSteps = 1e13;  // (particles + nodes) x steps: days of stepping
// Throws InputError when estimate_scene exceeds a limit above or the machine's physical memory
// (sysconf); `memory_limit_bytes` <= 0 means the physical memory.
void check_scene_size(const Scene& scene, double memory_limit_bytes = 0.0);

}  // namespace bsms::mpm
