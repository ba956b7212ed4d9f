// The family factory: reads the common keys of a family file and hands its "sample" section to the
// sampler named by "family" (families/*.cpp).
#include "data/generate/family.hpp"

#include "core/error.hpp"
#include "data/generate/families/samplers.hpp"
#include "data/mpm/scene_config.hpp"

namespace bsms::generate {

FamilyConfig parse_family(const Json& json, const std::string& file) {
  if (!json.is_object()) throw InputError(file + ": a family config must be a JSON object");
  FamilyConfig config;
  config.file = file;
  config.source = json;
  JsonObjectReader r(json, JsonContext{file, ""});
  config.family = r.get<std::string>("family");
  r.opt<std::string>("description", "");
  families::FamilyBase common;
  common.file = file;
  common.base = r.raw("scene");
  if (!common.base.is_object()) throw InputError(r.context("scene").where() + " must be an object");
  if (!common.base.contains("bodies")) common.base["bodies"] = Json::array();
  if (!common.base.contains("dim") || !common.base["dim"].is_number_integer())
    throw InputError(file + ": missing required key 'scene.dim'");
  config.dim = common.dim = common.base["dim"].get<int>();
  config.frames = common.frames = r.get<int>("frames");
  require(config.frames >= 2, r.context("frames"), "at least 2");
  config.frame_dt = common.frame_dt = r.get<double>("frame_dt");
  require(config.frame_dt > 0.0, r.context("frame_dt"), "positive (seconds)");
  config.fields = common.fields = r.opt<std::vector<std::string>>("fields", {"velocity"});
  for (const auto& f : config.fields)
    require(f == "velocity" || f == "stress", r.context("fields"),
            "a list of 'velocity' and 'stress' (world_pos is always stored), got '" + f + "'");
  JsonObjectReader s(r.raw("sample"), r.context("sample"));
  if (config.family == "disks") {
    config.sampler = families::make_disks_sampler(common, s);
  } else if (config.family == "press") {
    config.sampler = families::make_press_sampler(common, s);
  } else if (config.family == "cantilever") {
    config.sampler = families::make_cantilever_sampler(common, s);
  } else if (config.family == "union") {
    config.sampler = families::make_union_sampler(common, s);
  } else if (config.family == "bodies") {
    config.sampler = families::make_bodies_sampler(common, s);
  } else {
    throw InputError(r.context("family").where() + ": unknown family '" + config.family +
                     "' (allowed: disks, press, cantilever, union, bodies)");
  }
  s.finish();
  r.finish();
  // Check the base scene and the materials: the scene parser sees one draw (no meshing).
  if (config.family != "union") {
    Rng rng(static_cast<uint64_t>(trajectory_seed(0, 0, 0)));
    const SampledScene draw = config.sampler->sample(rng, "");
    mpm::parse_scene(draw.scene, file + " (scene drawn from 'sample')");
  }
  return config;
}

FamilyConfig load_family(const std::string& path, const std::vector<std::string>& overrides) {
  Json json = load_json_file(path);
  for (const auto& o : overrides) apply_override(json, o, path);
  return parse_family(json, path);
}

}  // namespace bsms::generate
