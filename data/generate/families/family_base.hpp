// What every sampler shares: the family's base scene with its timing and output settings, which
// a draw completes with bodies, boundaries and gravity, and the base scene's background box.
#pragma once

#include <string>
#include <vector>

#include "core/config.hpp"

namespace bsms::generate::families {

constexpr double kPi = 3.14159265358979323846;

struct FamilyBase {
  Json base;         // the "scene" section
  std::string file;  // for messages
  int dim = 2;
  int frames = 0;
  double frame_dt = 0.0;  // s
  std::vector<std::string> fields;

  // The base scene with `bodies`, `boundaries` appended to its own, `gravity` (m/s², unless
  // empty), end_time = frame_dt (frames − 1) and the output frames and fields.
  Json finish(Json bodies, Json boundaries, const std::vector<double>& gravity) const;
};

// The background box of the base scene `scene` (read strictly, mpm::parse_base_scene), m [dim]
// each; InputError naming the key unless the base scene is valid with a box background.
void background_box(const Json& scene, const std::string& file, int dim, std::vector<double>& lo,
                    std::vector<double>& hi);

// A scene's uniform initial velocity `v` (m/s).
Json uniform_velocity(const std::vector<double>& v);

}  // namespace bsms::generate::families
