// Bi-stride pooling, second-order adjacency enhancement and transition weights (thesis §4.2,
// §4.3.2; docs/design.md "Bi-stride multilevel building").
#pragma once

#include <cstdint>
#include <vector>

#include "core/graph.hpp"
#include "preprocess/seeding.hpp"

namespace bsms {

// Pooled nodes, ascending. Per cluster: BFS from its seed, split by parity of BFS depth, keep the
// class with fewer nodes; ties or an empty odd class keep the even class (it holds the seed).
// `seeds` [clusters] gives one node of each cluster.
std::vector<int64_t> bi_stride_pool(const CsrGraph& graph, const ClusterNodes& clusters,
                                    const std::vector<int64_t>& seeds);

// ((A + I)^2 without the diagonal)[pooled, pooled]: pooled nodes (ascending) joined when within two
// hops in `graph`. Row r of the result is pooled[r]. Deterministic for any thread count.
CsrGraph enhance_adjacency(const CsrGraph& graph, const std::vector<int64_t>& pooled);

struct TransitionWeights {
  std::vector<float> down_weight;   // [E] per edge of `graph`, CSR order
  std::vector<double> node_weight;  // [pooled] accumulated node weight of the coarser level
};

// §4.3.2 for edges i->j of `graph` with node weights w [N]:
//   ŵ_ij = w_i / outdeg(i);  down_weight_ij = ŵ_ij / sum_{i'->j} ŵ_i'j;
//   next w_j = sum_{i->j} ŵ_ij for pooled j (a node without edges keeps its own weight).
TransitionWeights transition_weights(const CsrGraph& graph, const std::vector<double>& node_weight,
                                     const std::vector<int64_t>& pooled);

}  // namespace bsms
