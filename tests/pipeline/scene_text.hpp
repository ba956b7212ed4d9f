// Scene texts typed as a dataset types its stored scene (parse_dataset_scene), for the tests of
// what reads Dataset::parsed_scene.
#pragma once

#include <optional>
#include <string>

#include "data/dataset/dataset.hpp"
#include "data/mpm/scene_config.hpp"

namespace bsms::testing {

// `text` as a dataset of `dim` dimensions stores it: "{}" (none), a family file (its "scene", the
// base scene) or a scene file.
inline std::optional<mpm::Scene> typed_scene(const std::string& text, int dim = 2) {
  return parse_dataset_scene(text, dim, "test scene");
}

}  // namespace bsms::testing
