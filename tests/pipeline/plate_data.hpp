// Synthetic Lagrangian data for the pipeline tests: a triangulated plate moving under gravity and
// drag with a per-trajectory initial velocity and two pinned nodes, and a small training config.
#pragma once

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "data/dataset/dataset.hpp"
#include "tests/temp_dir.hpp"

namespace bsms::testing {

namespace fs = std::filesystem;

// A new empty folder of this test process (tests/temp_dir.hpp).
inline fs::path fresh_dir(const std::string& name) {
  return unique_temp_dir("pipeline_" + name);
}

// A plate under gravity and linear drag: v_{t+1} = (1 - c) v_t + g, so the acceleration per frame²
// is a_t = g - c v_t, a function of the velocity input; initial velocities differ per trajectory.
inline Trajectory dragged_plate(int64_t seed, int frames, int m = 6) {  // (m+1)^2 nodes
  Trajectory t;
  t.mesh.dim = 2;
  t.mesh.cell_size = 3;
  for (int j = 0; j <= m; ++j)
    for (int i = 0; i <= m; ++i) {
      t.mesh.mesh_pos.push_back(0.1f * i);
      t.mesh.mesh_pos.push_back(0.1f * j);
      t.mesh.node_type.push_back((i == 0 && (j == 0 || j == m)) ? 1 : 0);
      t.mesh.body_id.push_back(0);
    }
  for (int j = 0; j < m; ++j)
    for (int i = 0; i < m; ++i) {
      const int a = j * (m + 1) + i, b = a + 1, c = a + m + 1, d = c + 1;
      t.mesh.cells.insert(t.mesh.cells.end(), {a, b, d, a, d, c});
    }
  const int64_t n = t.mesh.num_nodes();
  t.seed = seed;
  t.num_frames = frames;
  const double angle = 0.7 * static_cast<double>(seed), drag = 0.1, g = -0.0005;
  double vx = 0.01 * std::cos(angle), vy = 0.01 * std::sin(angle), dx = 0, dy = 0;
  std::vector<float> pos(frames * n * 2);
  for (int f = 0; f < frames; ++f) {
    for (int64_t p = 0; p < n; ++p) {
      const bool pinned = t.mesh.node_type[p] == 1;
      pos[(f * n + p) * 2] = t.mesh.mesh_pos[2 * p] + static_cast<float>(pinned ? 0 : dx);
      pos[(f * n + p) * 2 + 1] = t.mesh.mesh_pos[2 * p + 1] + static_cast<float>(pinned ? 0 : dy);
    }
    dx += vx;
    dy += vy;
    vx = (1 - drag) * vx;
    vy = (1 - drag) * vy + g;
  }
  t.fields["world_pos"] = pos;
  return t;
}

// A known answer: a plate of unit masses joined by linear springs along its mesh edges, started
// from a random smooth deformation at rest and integrated exactly at frame resolution:
// x_{t+1} = 2 x_t - x_{t-1} + a_t with a_i = k Σ_j (|x_j - x_i| - |X_j - X_i|) (x_j - x_i) / |x_j -
// x_i|. The target acceleration is a sum over mesh edges of a function of the edge's strain and
// direction, so one message-passing layer with the strain channel represents it exactly.
inline Trajectory spring_plate(int64_t seed, int frames, int m = 6) {
  Trajectory t = dragged_plate(0, 1, m);
  const int64_t n = t.mesh.num_nodes();
  for (auto& type : t.mesh.node_type) type = 0;
  t.seed = seed;
  t.num_frames = frames;
  std::vector<std::pair<int, int>> springs;
  for (int64_t c = 0; c < t.mesh.num_cells(); ++c)
    for (int k = 0; k < 3; ++k) {
      const int a = t.mesh.cells[3 * c + k], b = t.mesh.cells[3 * c + (k + 1) % 3];
      springs.emplace_back(std::min(a, b), std::max(a, b));
    }
  std::sort(springs.begin(), springs.end());
  springs.erase(std::unique(springs.begin(), springs.end()), springs.end());
  const double stiffness = 0.05, phase = 0.9 * static_cast<double>(seed);
  std::vector<double> x(2 * n), prev(2 * n), rest(t.mesh.mesh_pos.begin(), t.mesh.mesh_pos.end());
  for (int64_t p = 0; p < n; ++p) {
    const double u = rest[2 * p], v = rest[2 * p + 1];
    x[2 * p] = u + 0.012 * std::sin(4.0 * v + phase) + 0.3 * u * 0.05 * std::cos(phase);
    x[2 * p + 1] = v + 0.012 * std::cos(5.0 * u - phase);
  }
  prev = x;
  std::vector<float> pos;
  for (int f = 0; f < frames; ++f) {
    for (double value : x) pos.push_back(static_cast<float>(value));
    std::vector<double> a(2 * n, 0.0);
    for (const auto& [i, j] : springs) {
      const double dx = x[2 * j] - x[2 * i], dy = x[2 * j + 1] - x[2 * i + 1];
      const double length = std::hypot(dx, dy);
      const double l0 = std::hypot(rest[2 * j] - rest[2 * i], rest[2 * j + 1] - rest[2 * i + 1]);
      const double f_over_l = stiffness * (length - l0) / length;
      a[2 * i] += f_over_l * dx;
      a[2 * i + 1] += f_over_l * dy;
      a[2 * j] -= f_over_l * dx;
      a[2 * j + 1] -= f_over_l * dy;
    }
    for (int64_t k = 0; k < 2 * n; ++k) {
      const double next = 2 * x[k] - prev[k] + a[k];
      prev[k] = x[k];
      x[k] = next;
    }
  }
  t.fields["world_pos"] = pos;
  return t;
}

// The scene stored with the plates by default, as `bsms generate` stores a family file: a base
// scene on a mesh background, so without a box (no walls, no symmetries, no momentum "auto") and
// without an element_size (the contact radius follows the mesh edges).
inline constexpr const char* kPlateScene = R"({"name": "plate", "scene": {"dim": 2,
    "background": {"type": "mesh", "path": "plate.msh"}, "solver": {"end_time": 1.0}}})";

// One split file of `count` trajectories made by `make(seed, frames, m)` (dragged_plate or
// spring_plate); validation and test seeds differ from the training ones. `scene`: the scene
// JSON stored with them (default: kPlateScene).
using PlateMaker = Trajectory (*)(int64_t, int, int);
inline void write_split(const fs::path& dir, const std::string& split, int count, int frames,
                        int m = 6, PlateMaker make = dragged_plate, const char* scene = nullptr) {
  if (!scene) scene = kPlateScene;
  DatasetWriter w((dir / (split + ".h5")).string(), scene, 2, 0.01);
  for (int i = 0; i < count; ++i) {
    Trajectory t = make(i + (split == "train" ? 0 : 100), frames, m);
    t.solver_wall_s = 0.5;
    w.add(t);
  }
  w.commit();
}

inline std::string write_config(const fs::path& dir, const fs::path& data, const std::string& model,
                                int64_t steps) {
  const std::string path = (dir / (model + ".json")).string();
  std::ofstream(path) << R"({"data": ")" << data.string() << R"(", "steps": )" << steps
                      << R"(, "valid_every": 20, "valid_samples": 4, "normalizer_steps": 20,
    "model": {"type": ")"
                      << model << R"(", "latent": 16, "levels": 3, "message_passing_steps": 2},
    "features": {"noise_std": 0.0},
    "optimizer": {"lr": 3e-3, "lr_final": 3e-4, "batch_size": 2}})";
  return path;
}

}  // namespace bsms::testing
