// Seed selection for bi-stride pooling: one seed per cluster (connected component).
#pragma once

#include <cstdint>
#include <vector>

#include "core/graph.hpp"
#include "core/mesh.hpp"

namespace bsms {

// The nodes of each cluster: cluster c holds nodes[offsets[c] .. offsets[c+1]), ascending.
// Clusters are numbered like Components (by their lowest node).
struct ClusterNodes {
  int64_t count = 0;
  std::vector<int64_t> offsets;  // [count + 1]
  std::vector<int64_t> nodes;    // [N]
  int64_t size(int64_t c) const { return offsets[c + 1] - offsets[c]; }
  const int64_t* begin(int64_t c) const { return nodes.data() + offsets[c]; }
  const int64_t* end(int64_t c) const { return nodes.data() + offsets[c + 1]; }
};
ClusterNodes group_clusters(const Components& components);

// CloseCenter: per cluster the node nearest (Euclidean) to the mean of its positions [N, dim];
// ties: lowest index. The mean sums positions in ascending node order. Returns [clusters].
std::vector<int64_t> close_center_seeds(const ClusterNodes& clusters, const RowMatrixXd& positions);

// Work counters of an exact MinAve search (for benchmarks and tests).
struct MinAveStats {
  int64_t bound_bfs = 0;  // multi-source BFS runs (one per blob of ~64 nodes) for lower bounds
  int64_t evaluated = 0;  // candidates whose BFS was started (bit-parallel, up to 64 per pass)
  int64_t batches = 0;    // bit-parallel passes
  int64_t pruned = 0;     // candidates rejected by the lower bound alone, without any BFS
};

// MinAve: per cluster the node with the minimum sum (equivalently average) of BFS distances to
// the other nodes of its cluster; ties: lowest index. Exact. The cluster is split into compact
// blobs B of ~64 nodes; one multi-source BFS per blob gives d(v, B), and
// sum_B |B| d(v, B) <= sum of distances of v (triangle inequality) bounds every node from below.
// Candidates are then evaluated blob by blob, 64 at a time, with a bit-parallel multi-source BFS
// that drops a source as soon as its partial bound exceeds the best sum found.
std::vector<int64_t> min_ave_seeds(const CsrGraph& graph, const ClusterNodes& clusters,
                                   MinAveStats* stats = nullptr);

// Sums of BFS distances from each of up to 64 `sources` of one cluster of `cluster_size` nodes
// (no pruning). Exposed for tests and benchmarks.
std::vector<int64_t> distance_sums(const CsrGraph& graph, const std::vector<int64_t>& sources,
                                   int64_t cluster_size);

// The lower bounds MinAve prunes with: for each node of `cluster_nodes` (one whole cluster,
// ascending), sum_B |B| d(v, B) over its blobs B. Exposed for tests.
std::vector<int64_t> distance_sum_lower_bounds(const CsrGraph& graph,
                                               const std::vector<int64_t>& cluster_nodes);

// Random: per cluster a node drawn from a counter-based generator keyed by (seed, cluster), so the
// choice depends only on the seed and the cluster, never on threads.
std::vector<int64_t> random_seeds(const ClusterNodes& clusters, uint64_t rng_seed);

}  // namespace bsms
