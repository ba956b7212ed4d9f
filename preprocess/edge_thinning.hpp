// Thinning of coarse levels (a deliberate deviation from docs/design.md's exact A², used by
// `--levels auto` and on request).
//
// Why: bi-stride pooling keeps whole BFS fronts. On a 2D mesh the kept rings thin out radially
// (every other ring) but keep their full resolution along the ring, so A² joins each node to
// ~2^k ring neighbours at level k: the mean degree roughly doubles per level while the node count
// halves, and every coarse level costs about as much as the mesh (a 1M-node plate: 9 levels, 5.8×
// the edges of level 0). Thinning keeps, for each node whose degree exceeds 2·C, its nearest and
// its farthest neighbour in each of C direction cones (a Yao-graph-like choice among the A²
// neighbours): the nearest keep the level locally connected, the farthest keep its reach (the hop
// distance a message travels per layer), and the degree stays bounded, so the edges of a level
// shrink with its nodes. An edge is kept when either end keeps it (the graph stays symmetric).
// Edges are only removed, so no edge joins two clusters; if removing them would split a cluster,
// the shortest removed edges joining the parts are put back, so clusters are unchanged.
// Deterministic and independent of the thread count.
#pragma once

#include <cstdint>

#include "core/graph.hpp"
#include "core/mesh.hpp"

namespace bsms {

// Direction cones per spatial dimension: 2 (1D), 8 (2D, 45° sectors), 14 (3D: the 6 axis and 8
// diagonal directions; a neighbour belongs to the direction it is most aligned with).
int thinning_cones(int dim);

struct ThinningReport {
  int64_t thinned_nodes = 0;   // nodes whose degree exceeded 2·cones
  int64_t restored_edges = 0;  // directed edges put back to keep clusters connected
};

// `graph` symmetric with sorted neighbours (as built here), `positions` [N, dim] (dim 1..3).
CsrGraph thin_adjacency(const CsrGraph& graph, const RowMatrixXd& positions,
                        ThinningReport* report = nullptr);

}  // namespace bsms
