#include "pipeline/adapters/scene_features.hpp"

#include <algorithm>
#include <cmath>
#include <set>

#include "data/mpm/background.hpp"
#include "data/mpm/scene_config.hpp"

namespace bsms {

namespace {

// Every boundary of the scene is "slip" or "roller": its walls push only along their normals.
// No scene has no boundary.
bool slip_walls_only(const std::optional<mpm::Scene>& scene) {
  if (!scene) return true;
  for (const auto& b : scene->boundaries)
    if (b.type != mpm::BoundaryType::kSlip && b.type != mpm::BoundaryType::kRoller) return false;
  return true;
}

}  // namespace

void resolve_contact_radius(LagrangianSpec& spec, const std::optional<mpm::Scene>& scene,
                            double mean_edge) {
  double radius = 1.5 * mean_edge;
  // element_size is 0 where the background has none (a mesh background).
  if (scene) radius = std::max(radius, 1.5 * scene->background.element_size);
  spec.contact_radius = radius;
}

void resolve_walls(LagrangianSpec& spec, const std::optional<mpm::Scene>& scene, double radius) {
  spec.wall_lo.clear();
  spec.wall_hi.clear();
  spec.wall_radius = 0.0;
  if (!scene || scene->background.type != "box" || scene->dim != spec.dim) return;
  std::set<std::string> groups;
  for (const auto& b : scene->boundaries)
    if (!b.group.empty()) groups.insert(b.group);
  bool any = false;
  for (int a = 0; a < spec.dim; ++a) {
    const bool lo = groups.count(mpm::box_side_name(a, false)) > 0,
               hi = groups.count(mpm::box_side_name(a, true)) > 0;
    spec.wall_lo.push_back(lo ? scene->background.min[a] : std::nan(""));
    spec.wall_hi.push_back(hi ? scene->background.max[a] : std::nan(""));
    any = any || lo || hi;
  }
  if (any) {
    spec.wall_radius = radius;
  } else {
    spec.wall_lo.clear();
    spec.wall_hi.clear();
  }
}

LagrangianSpec walls_for_scene(LagrangianSpec spec, const std::optional<mpm::Scene>& scene) {
  if (!spec.has_walls()) return spec;
  const double radius = spec.wall_radius;
  resolve_walls(spec, scene, radius);
  // The tangential part of the projection holds only where every wall still slips.
  if (spec.momentum_slip_walls) spec.momentum_slip_walls = slip_walls_only(scene);
  if (!spec.has_walls()) {
    spec.wall_lo.assign(spec.dim, std::nan(""));
    spec.wall_hi.assign(spec.dim, std::nan(""));
    spec.wall_radius = radius;
  }
  return spec;
}

std::string resolve_momentum(LagrangianSpec& spec, const std::optional<mpm::Scene>& scene,
                             bool at_walls) {
  spec.momentum_radius = spec.momentum_wall_range = 0.0;
  spec.momentum_slip_walls = false;
  if (scene &&
      std::any_of(scene->gravity.begin(), scene->gravity.end(), [](double g) { return g != 0.0; }))
    return "the scene has gravity";
  if (!scene || scene->background.type != "box" || scene->background.rotation_deg != 0.0)
    return "the scene has no axis-aligned box background with an element_size";
  if (!spec.has_walls()) return "the model has no wall inputs";
  std::set<std::string> sides;
  for (int a = 0; a < 3; ++a)
    for (bool high : {false, true}) sides.insert(mpm::box_side_name(a, high));
  for (const auto& b : scene->boundaries)
    if (sides.count(b.group) == 0) return "the scene has a boundary that is not a side of its box";
  // A box background's element_size is > 0 (the scene parser requires it).
  const double h = scene->background.element_size;
  spec.momentum_radius = 3.0 * h;
  spec.momentum_wall_range = 2.0 * h;
  spec.momentum_slip_walls = at_walls && slip_walls_only(scene);
  return "";
}

}  // namespace bsms
