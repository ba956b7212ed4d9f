// Multilevel graphs by spatial proximity: the MS-GNN-GRID-style coarsening that BSMS-GNN is
// compared against in thesis §4.4 (Figure 4.6). Coarse nodes are the occupied cells of regular
// grids and coarse edges join neighbouring cells, whatever the mesh connectivity, so nodes that are
// close in space but far apart on the mesh (two bodies across a thin gap) get pooled or joined.
// Index form, like bi-stride pooling's MultilevelGraph; src/pipeline/graphs/multilevel_tensors.hpp
// turns it into the models' tensors.
#pragma once

#include <cstdint>
#include <vector>

#include "core/graph.hpp"
#include "core/mesh.hpp"

namespace bsms {

// Level k of a proximity multilevel graph. The transition from level k-1 (k >= 1) pools each
// level-(k-1) node into the cell it lies in: down = mean of the cell's members, up = the cell's
// value given to each member.
struct ProximityLevel {
  int64_t num_nodes = 0;
  EdgeList edges;  // directed (sender, receiver) among this level's nodes
  // (k >= 1) cluster_of [N_(k-1)]: the level-k node of each level-(k-1) node. Cell c's members
  // are members[member_offsets[c] .. member_offsets[c+1]), ascending, each with member_weight
  // 1 / (number of members) (float, as the models use it).
  std::vector<int64_t> cluster_of;
  std::vector<int64_t> member_offsets;  // [N_k + 1]
  std::vector<int64_t> members;         // [N_(k-1)]
  std::vector<float> member_weight;     // [N_(k-1)]
  // [N_k, d]: level 0 the input positions, level k >= 1 the mean of the cell's members.
  RowMatrixXd positions;
};

struct ProximityMultilevelGraph {
  std::vector<ProximityLevel> levels;  // levels[0] is the input graph
  int num_levels() const { return static_cast<int>(levels.size()); }
};

// `num_levels` levels (>= 1) for nodes at `positions` [N, d] (N >= 1, d in 1..3):
// - level 0: `level0_edges` (sender, receiver) as given (any order, duplicates kept);
// - level k >= 1: a grid of cell size cell_size * 2^(k-1) anchored at the origin; one node per cell
//   occupied by a level-(k-1) node, numbered by integer cell coordinates (lexicographic, axis 0
//   first), placed at the mean of its members; edges join occupied cells whose integer
//   coordinates differ by at most 1 per axis (both directions, no self loops), grouped by sender
//   in node order, each sender's receivers in the order of the offsets in {-1, 0, 1}^d with
//   axis 0 varying fastest (ascending in 1-D).
// Deterministic. InputError on a bad shape, non-finite positions, a node more than 1e15 cells
// from the origin, edges outside [0, N), num_levels < 1 or cell_size not positive and finite.
ProximityMultilevelGraph build_proximity_multilevel_graph(const RowMatrixXd& positions,
                                                          const EdgeList& level0_edges,
                                                          int num_levels, double cell_size);

}  // namespace bsms
