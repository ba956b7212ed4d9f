// Compressed sparse row graphs, connected components and breadth-first search.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "core/mesh.hpp"

namespace bsms {

// Directed edge list, [E, 2] as (sender, receiver) pairs stored flat: s0, r0, s1, r1, ...
struct EdgeList {
  std::vector<int64_t> data;
  int64_t size() const { return static_cast<int64_t>(data.size() / 2); }
  int64_t sender(int64_t e) const { return data[2 * e]; }
  int64_t receiver(int64_t e) const { return data[2 * e + 1]; }
};

// Adjacency in CSR form: neighbours of node i are targets[offsets[i] .. offsets[i+1]).
// Graphs built here are symmetric, without self loops, neighbours sorted ascending.
struct CsrGraph {
  int64_t num_nodes = 0;
  std::vector<int64_t> offsets;  // [N + 1]
  std::vector<int64_t> targets;  // [E]

  int64_t num_edges() const { return static_cast<int64_t>(targets.size()); }
  int64_t degree(int64_t i) const { return offsets[i + 1] - offsets[i]; }
  const int64_t* begin(int64_t i) const { return targets.data() + offsets[i]; }
  const int64_t* end(int64_t i) const { return targets.data() + offsets[i + 1]; }

  // All directed edges (i, j) for j in N(i), in CSR order: sorted by sender then receiver.
  EdgeList edges() const;
};

// Builds a symmetric CSR graph from undirected or directed pairs: adds both directions, drops self
// loops and duplicates. Pairs are given flat (a0, b0, a1, b1, ...).
CsrGraph graph_from_pairs(int64_t num_nodes, const std::vector<int64_t>& pairs);

// The graph of a mesh: every pair of nodes sharing a cell is joined (both directions).
CsrGraph mesh_graph(const Mesh& mesh);

// Connected components: label[i] in [0, num_components), components numbered by their lowest node.
struct Components {
  int64_t count = 0;
  std::vector<int64_t> label;  // [N]
};
Components connected_components(const CsrGraph& graph);

constexpr int64_t kUnreached = -1;

// BFS depth of every node from `source` (kUnreached where not reachable).
std::vector<int64_t> bfs_depths(const CsrGraph& graph, int64_t source);

}  // namespace bsms
