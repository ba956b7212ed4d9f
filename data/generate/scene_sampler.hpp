// What a scene family draws (family.hpp): one concrete scene per trajectory from a seeded random
// stream, and the rules that classify its nodes. Each family (data/generate/families/) implements
// SceneSampler.
#pragma once

#include <string>
#include <vector>

#include "core/config.hpp"
#include "data/generate/rng.hpp"

namespace bsms::generate {

// Node classification rule: nodes with (x − point)·normal ≥ −tolerance are fixed (node_type 1).
struct FixedPlane {
  std::vector<double> point, normal;  // m [dim], unit normal
  double tolerance = 1e-9;            // m
};

// One concrete scene drawn from a family.
struct SampledScene {
  Json scene;                        // a complete scene JSON (parse_scene accepts it)
  Json parameters;                   // the sampled values, for the dataset's parameters attribute
  std::vector<FixedPlane> fixed;     // node_type 1 rules
  std::vector<int> actuator_bodies;  // bodies whose nodes get node_type 2
  std::vector<std::string> work_files;  // files written for this draw (removed after building)
};

class SceneSampler {
 public:
  virtual ~SceneSampler() = default;
  // Draws a scene from `rng`. Files the scene needs (e.g. gmsh geometry) are written with the
  // path prefix `work_prefix` and listed in work_files. InputError when the ranges cannot be met.
  virtual SampledScene sample(Rng& rng, const std::string& work_prefix) const = 0;
};

}  // namespace bsms::generate
