// The Lagrangian features a dataset's scene decides (contact radius, walls, momentum "auto"), read
// from the typed scene (Dataset::parsed_scene: a scene file's scene or a family file's base scene;
// none for public data). The scene parser holds every default, so nothing here reads scene JSON.
#pragma once

#include <optional>
#include <string>

#include "pipeline/adapters/lagrangian.hpp"

namespace bsms {

namespace mpm {
struct Scene;
}

// Contact radius "auto": the range at which two bodies of the scene's solver already interact,
// 1.5 background cells (the kernel support; the background's element_size, m), and at least 1.5
// mean mesh edges `mean_edge` (m; public data and mesh backgrounds have no element_size).
void resolve_contact_radius(LagrangianSpec& spec, const std::optional<mpm::Scene>& scene,
                            double mean_edge);

// Momentum "auto", from the scene alone: on when the scene has no gravity, an unrotated "box"
// background of element_size h whose only boundaries are named box sides (walls), and the spec has
// those walls: then momentum_radius = 3 h (two particles within two kernel supports of 1.5 h share
// grid nodes) and momentum_wall_range = 2 h (the kernel support plus a cell of travel). With
// `at_walls`, momentum_slip_walls is set when every boundary is "slip" or "roller". Leaves momentum
// off otherwise and returns why.
std::string resolve_momentum(LagrangianSpec& spec, const std::optional<mpm::Scene>& scene,
                             bool at_walls = true);

// Sets spec.wall_lo/wall_hi (m) and wall_radius = `radius` (m) from the scene: a "box" background
// of spec.dim dimensions whose sides are named in its boundaries (left/right, bottom/top,
// back/front). Leaves the spec without walls otherwise.
void resolve_walls(LagrangianSpec& spec, const std::optional<mpm::Scene>& scene, double radius);

// A trained spec with wall inputs, moved to another scene (e.g. a larger box for a zero-shot
// rollout): the walls of that scene with the trained radius; a scene without walls reads as "far
// from every wall", so the input size never changes. A spec without walls is returned as is.
LagrangianSpec walls_for_scene(LagrangianSpec spec, const std::optional<mpm::Scene>& scene);

}  // namespace bsms
