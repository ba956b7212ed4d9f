// Small meshes and a brute-force bi-stride builder (docs/design.md "Bi-stride multilevel building"
// items 1-6, lowest-index seeds) for the model tests, independent of preprocess/ (as models/ is).
#pragma once

#include <torch/types.h>

#include <algorithm>
#include <cstdint>
#include <vector>

#include "core/graph.hpp"
#include "models/graph_tensors.hpp"

namespace bsms::testing {

// Structured triangulated nx × ny grid on [0, nx-1] × [0, ny-1]; node (x, y) = y * nx + x.
struct GridMesh {
  CsrGraph graph;
  torch::Tensor positions;  // [N, 2] float32
};

inline GridMesh grid_mesh(int64_t nx, int64_t ny) {
  std::vector<int64_t> pairs;
  auto id = [&](int64_t x, int64_t y) { return y * nx + x; };
  for (int64_t y = 0; y < ny; ++y) {
    for (int64_t x = 0; x < nx; ++x) {
      if (x + 1 < nx) pairs.insert(pairs.end(), {id(x, y), id(x + 1, y)});
      if (y + 1 < ny) pairs.insert(pairs.end(), {id(x, y), id(x, y + 1)});
      if (x + 1 < nx && y + 1 < ny) pairs.insert(pairs.end(), {id(x, y), id(x + 1, y + 1)});
    }
  }
  GridMesh mesh;
  mesh.graph = graph_from_pairs(nx * ny, pairs);
  auto idx = torch::arange(nx * ny, torch::kInt64);
  mesh.positions = torch::stack({idx.remainder(nx), idx.div(nx, "floor")}, 1).to(torch::kFloat32);
  return mesh;
}

// One level in the index form of preprocess/'s GraphLevel (and of the multilevel file).
struct ReferenceLevel {
  CsrGraph graph;                  // symmetric adjacency among this level's nodes
  std::vector<int64_t> pooled;     // (k >= 1) indices into level k-1 kept at level k, ascending
  std::vector<float> down_weight;  // (k >= 1) weight of each level-(k-1) edge, CSR edge order
  int64_t num_nodes() const { return graph.num_nodes; }
};

struct ReferenceMultilevel {
  std::vector<ReferenceLevel> levels;  // levels[0] is the mesh graph
};

// Bi-stride levels with the lowest node of each cluster as seed; weights per docs/design.md
// "Bi-stride multilevel building" item 6.
inline ReferenceMultilevel reference_multilevel(const CsrGraph& mesh_graph, int num_levels) {
  ReferenceMultilevel out;
  out.levels.emplace_back();
  out.levels.back().graph = mesh_graph;
  std::vector<double> w(mesh_graph.num_nodes, 1.0);
  for (int k = 1; k < num_levels; ++k) {
    const CsrGraph& g = out.levels.back().graph;
    const int64_t n = g.num_nodes;
    std::vector<int64_t> depth(n, kUnreached);
    std::vector<char> keep(n, 0);
    for (int64_t seed = 0; seed < n; ++seed) {
      if (depth[seed] != kUnreached) continue;
      auto d = bfs_depths(g, seed);
      std::vector<int64_t> even, odd;
      for (int64_t i = 0; i < n; ++i) {
        if (d[i] == kUnreached) continue;
        depth[i] = d[i];
        (d[i] % 2 == 0 ? even : odd).push_back(i);
      }
      const auto& kept = (even.size() <= odd.size() || odd.empty()) ? even : odd;
      for (int64_t i : kept) keep[i] = 1;
    }
    ReferenceLevel level;
    std::vector<int64_t> coarse(n, -1);
    for (int64_t i = 0; i < n; ++i) {
      if (keep[i]) {
        coarse[i] = static_cast<int64_t>(level.pooled.size());
        level.pooled.push_back(i);
      }
    }
    std::vector<int64_t> pairs;
    for (int64_t a : level.pooled) {
      std::vector<int64_t> hop1(g.begin(a), g.end(a));
      hop1.push_back(a);
      for (int64_t b : hop1) {
        for (const int64_t* c = g.begin(b); c != g.end(b); ++c) {
          if (keep[*c] && *c != a) pairs.insert(pairs.end(), {coarse[a], coarse[*c]});
        }
      }
    }
    level.graph = graph_from_pairs(static_cast<int64_t>(level.pooled.size()), pairs);
    std::vector<double> what(g.num_edges()), total(n, 0.0);
    for (int64_t i = 0; i < n; ++i) {
      for (int64_t p = g.offsets[i]; p < g.offsets[i + 1]; ++p) {
        what[p] = w[i] / static_cast<double>(g.degree(i));
        total[g.targets[p]] += what[p];
      }
    }
    level.down_weight.resize(g.num_edges());
    for (int64_t p = 0; p < g.num_edges(); ++p) {
      level.down_weight[p] = static_cast<float>(what[p] / total[g.targets[p]]);
    }
    std::vector<double> next;
    for (int64_t i : level.pooled) next.push_back(g.degree(i) > 0 ? total[i] : w[i]);
    w = next;
    out.levels.push_back(std::move(level));
  }
  return out;
}

// The tensors of a reference multilevel graph, assembled as
// src/pipeline/graphs/multilevel_tensors.hpp assembles them from a MultilevelGraph (transitions[0]
// empty, transitions[k] joins k-1 and k).
inline MultilevelTensors reference_tensors(const ReferenceMultilevel& graph) {
  MultilevelTensors h;
  for (size_t k = 0; k < graph.levels.size(); ++k) {
    const ReferenceLevel& level = graph.levels[k];
    h.edge_sets.push_back({EdgeIndex::from_csr(level.graph)});
    h.node_offsets.push_back({0, level.num_nodes()});
    h.transitions.push_back(
        k > 0 ? LevelTransition::from_down_weights(graph.levels[k - 1].graph, level.pooled,
                                                   level.down_weight, static_cast<int>(k))
              : LevelTransition{});
  }
  return h;
}

}  // namespace bsms::testing
