// The five scene families, one file each; parse_family (family.cpp) picks one by the config's
// "family" key. Each reads its "sample" section from `r` strictly (the caller finishes `r`) and
// checks that the ranges fit the base scene (InputError naming the file and key).
#pragma once

#include <memory>

#include "core/config.hpp"
#include "data/generate/families/family_base.hpp"
#include "data/generate/scene_sampler.hpp"

namespace bsms::generate::families {

// disks.cpp: 2–4 elastic disks of random size and velocity colliding in a box.
std::shared_ptr<const SceneSampler> make_disks_sampler(FamilyBase base, JsonObjectReader& r);
// press.cpp: a stiff, heavy actuator pressing into an elastic plate clamped at y = 0.
std::shared_ptr<const SceneSampler> make_press_sampler(FamilyBase base, JsonObjectReader& r);
// cantilever.cpp: a beam clamped at x = 0 under a random load and material.
std::shared_ptr<const SceneSampler> make_cantilever_sampler(FamilyBase base, JsonObjectReader& r);
// union.cpp: a gmsh boolean union of random shapes dropped onto the floor.
std::shared_ptr<const SceneSampler> make_union_sampler(FamilyBase base, JsonObjectReader& r);
// bodies.cpp: 2–4 spheres and boxes (disks and rectangles in 2D) thrown at each other, 2D or 3D.
std::shared_ptr<const SceneSampler> make_bodies_sampler(FamilyBase base, JsonObjectReader& r);

}  // namespace bsms::generate::families
