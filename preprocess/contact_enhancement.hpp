// Contact edges carried down the levels (thesis eq. 4.1): Aᶜ_{k+1} = ((A_k+I) Aᶜ_k (A_k+I))[kept,
// kept]. Contact edges are dynamic (rebuilt every frame from spatial proximity), so this runs per
// frame in training: sparse row-by-row products with marker arrays, parallel over rows,
// deterministic. Note the formula grows contact sets level by level (each contact pair spreads
// to the kept neighbourhoods of both ends), so contacts spread over a whole mesh reach a nearly
// complete graph on coarse levels.
#pragma once

#include <vector>

#include "core/graph.hpp"
#include "preprocess/multilevel_graph.hpp"

namespace bsms {

// Contact edges (sender, receiver) [E_c, 2] among level-k nodes -> contact edges among level-(k+1)
// nodes: (a, b) for kept a in N[i], kept b in N[j] of some contact edge (i, j), where N[.] is the
// closed neighbourhood in level k. Sorted, unique; the formula is kept exactly, so (a, a) appears
// when both ends of a contact edge share a kept neighbour (callers may drop such loops).
// `level` is k, 0 <= k < num_levels - 1. Throws InputError on an out-of-range node index.
EdgeList enhance_contact_edges(const MultilevelGraph& graph, int level, const EdgeList& contact);

// All levels at once: result[0] = `contact` sorted and unique, result[k] for level k.
std::vector<EdgeList> enhance_contact_edges_all_levels(const MultilevelGraph& graph,
                                                       const EdgeList& contact);

}  // namespace bsms
