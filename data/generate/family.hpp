// Scene families for dataset generation (configs/families/*.json): a base scene (the JSON of
// configs/scenes/*.json, inline under "scene") plus a "sample" section of parameter ranges. A
// family-specific sampler turns a seeded random stream into one concrete scene per trajectory
// (bodies, sizes, positions, velocities, materials, gravity). Families: "disks", "press",
// "cantilever", "union", "bodies", one file each in data/generate/families/; this file's
// parse_family is the factory keyed by "family".
//
// Family file (strict; unknown keys, min > max and non-positive sizes are InputErrors):
//   {"family": "disks", "scene": {...}, "frames": 50, "frame_dt": 0.03,
//    "fields": ["velocity"], "sample": {...family keys...}}
// A range is a number (fixed), [min, max] (uniform) or {"log_uniform": [min, max]}; an integer
// range is sampled inclusively.
// Sample keys (lengths m, speeds m/s, angles degrees, accelerations m/s², materials as in scenes
// with a range per numeric parameter):
//   disks       count, radius, spacing, speed, gap, aim_jitter_deg, material, gravity (per axis)
//   press       plate_width, plate_thickness, plate_spacing, plate_material, actuator_radius,
//               actuator_spacing, actuator_speed, actuator_offset (share of the plate half-width),
//               actuator_gap, actuator_material
//   cantilever  length, thickness, spacing, material, load, load_angle_deg (0 = down)
//   union       arm_length, arm_width, gap, base_height, disks, disk_radius, rotation_deg,
//               spacing, speed, clearance, material, gravity (per axis)
//   bodies      count (>= 2), shapes (sphere/disk, box), size (radius or half edge), box_aspect
//               (per-axis factor on the half edge), spacing, speed, gap, aim_jitter_deg,
//               contact_within (share of the duration by which the first two bodies meet),
//               nodes (estimated mesh nodes of a draw, [min, max]), material, gravity (per
//               axis); 2D or 3D
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/config.hpp"
#include "data/generate/scene_sampler.hpp"

namespace bsms::generate {

struct FamilyConfig {
  std::string file;    // for messages
  Json source;         // resolved JSON (after --set overrides), recorded next to outputs
  std::string family;  // "disks" | "press" | "cantilever" | "union" | "bodies"
  int dim = 2;
  int frames = 0;                   // frames stored per trajectory, t = 0 included
  double frame_dt = 0.0;            // s between stored frames
  std::vector<std::string> fields;  // stored besides world_pos: "velocity", "stress"
  std::shared_ptr<const SceneSampler> sampler;
};

// Parses a family config strictly and checks it by drawing and parsing one scene.
FamilyConfig parse_family(const Json& json, const std::string& file);
// Loads a family file and applies `--set key.path=value` overrides before parsing.
FamilyConfig load_family(const std::string& path, const std::vector<std::string>& overrides = {});

}  // namespace bsms::generate
