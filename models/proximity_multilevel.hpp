// Multilevel graphs by spatial proximity: the MS-GNN-GRID-style coarsening that BSMS-GNN is
// compared against in thesis §4.4 (Figure 4.6). Coarse nodes are the occupied cells of regular
// grids and coarse edges join neighbouring cells, whatever the mesh connectivity, so nodes that are
// close in space but far apart on the mesh (two bodies across a thin gap) get pooled or joined.
#pragma once

#include <torch/types.h>

#include "models/graph_tensors.hpp"

namespace bsms {

// A hierarchy of `num_levels` levels (>= 1) for nodes at `positions` [N, d] (float, d in 1..3):
// - level 0: the mesh edges `level0_edges` [E, 2] int64 (sender, receiver), used as given;
// - level k >= 1: a grid of cell size cell_size * 2^(k-1) anchored at the origin; one node per cell
//   occupied by a level-(k-1) node (ordered by integer cell coordinates), placed at the mean of its
//   members; edges join occupied cells whose integer coordinates differ by at most 1 per axis (both
//   directions, no self loops);
// - transition k -> k+1: down = mean of the members (weight 1 / count), up = broadcast of the
//   cell's value to each member (weight 1); up_is_down_transpose is false.
// One graph (node_offsets {0, N_k}), ready for merge_multilevel_tensors(). InputError on a bad
// shape, non-finite positions, edges outside [0, N), num_levels < 1 or cell_size not positive.
MultilevelTensors make_proximity_multilevel(const torch::Tensor& positions,
                                            const torch::Tensor& level0_edges, int num_levels,
                                            double cell_size);

}  // namespace bsms
