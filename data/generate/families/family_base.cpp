#include "data/generate/families/family_base.hpp"

#include <utility>

#include "core/error.hpp"
#include "data/mpm/scene_config.hpp"

namespace bsms::generate::families {

Json FamilyBase::finish(Json bodies, Json boundaries, const std::vector<double>& gravity) const {
  Json s = base;
  s["bodies"] = std::move(bodies);
  if (!boundaries.empty()) {
    Json all = s.contains("boundaries") ? s["boundaries"] : Json::array();
    for (auto& b : boundaries) all.push_back(b);
    s["boundaries"] = all;
  }
  if (!gravity.empty()) s["gravity"] = gravity;
  s["solver"]["end_time"] = frame_dt * (frames - 1);
  s["output"] = {{"frames", frames}, {"fields", fields}};
  return s;
}

void background_box(const Json& scene, const std::string& file, int dim, std::vector<double>& lo,
                    std::vector<double>& hi) {
  // Read by the scene parser, which holds the keys' defaults and checks (corners of scene.dim
  // numbers, max > min); `dim` is that scene.dim. The keys are recorded (ConfigKeyRecorder) under
  // a file name of their own: they are scene keys, not the family's.
  const mpm::Scene base =
      mpm::parse_base_scene(scene, JsonContext{file + " (base scene)", "scene"});
  if (base.background.type != "box" || base.dim != dim)
    throw InputError(JsonContext{file, "scene.background"}.where() +
                     " must be a box background (the samplers place bodies in it)");
  lo = base.background.min;
  hi = base.background.max;
}

Json uniform_velocity(const std::vector<double>& v) {
  return {{"type", "uniform"}, {"value", v}};
}

}  // namespace bsms::generate::families
