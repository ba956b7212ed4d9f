// Synthetic Lagrangian data for the pipeline tests: a triangulated plate moving under gravity and
// drag with a per-trajectory initial velocity and two pinned nodes, and a small training config.
#pragma once

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "data/dataset/dataset.hpp"

namespace bsms::testing {

namespace fs = std::filesystem;

inline fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("bsms_pipeline_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
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

inline void write_split(const fs::path& dir, const std::string& split, int count, int frames,
                        int m = 6) {
  DatasetWriter w((dir / (split + ".h5")).string(), R"({"name": "falling_plate"})", 2, 0.01);
  for (int i = 0; i < count; ++i) {
    Trajectory t = dragged_plate(i + (split == "train" ? 0 : 100), frames, m);
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
