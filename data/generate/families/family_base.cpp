#include "data/generate/families/family_base.hpp"

#include <utility>

#include "core/error.hpp"

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
  const JsonContext ctx{file, "scene.background"};
  if (!scene.contains("background") || !scene["background"].is_object() ||
      scene["background"].value("type", "") != "box")
    throw InputError(ctx.where() + " must be a box background (the samplers place bodies in it)");
  try {
    lo = scene["background"].at("min").get<std::vector<double>>();
    hi = scene["background"].at("max").get<std::vector<double>>();
  } catch (const nlohmann::json::exception&) {
    throw InputError(ctx.where() + " needs numeric 'min' and 'max' corners");
  }
  // The samplers index the corners by axis: a short corner must not be read past its end.
  if (static_cast<int>(lo.size()) != dim || static_cast<int>(hi.size()) != dim)
    throw InputError(ctx.where() + ": 'min' and 'max' must hold " + std::to_string(dim) +
                     " numbers (scene.dim)");
}

Json uniform_velocity(const std::vector<double>& v) {
  return {{"type", "uniform"}, {"value", v}};
}

}  // namespace bsms::generate::families
