#include "preprocess/bi_stride_pooling.hpp"

#include <omp.h>

#include <algorithm>

namespace bsms {

namespace {
// Below this many nodes a parallel region costs more than it saves.
constexpr int64_t kParallelNodes = 16384;
}  // namespace

std::vector<int64_t> bi_stride_pool(const CsrGraph& graph, const ClusterNodes& clusters,
                                    const std::vector<int64_t>& seeds) {
  const int64_t n = graph.num_nodes;
  // One BFS started from all seeds at once: clusters are disjoint, so each node gets its depth
  // from its own cluster's seed.
  std::vector<int32_t> depth(n, -1);
  std::vector<int64_t> owner(n, -1);
  std::vector<int64_t> queue;
  queue.reserve(n);
  for (int64_t c = 0; c < clusters.count; ++c) {
    depth[seeds[c]] = 0;
    owner[seeds[c]] = c;
    queue.push_back(seeds[c]);
  }
  std::vector<int64_t> odd(clusters.count, 0);
  for (size_t head = 0; head < queue.size(); ++head) {
    const int64_t u = queue[head];
    for (const int64_t* v = graph.begin(u); v != graph.end(u); ++v) {
      if (depth[*v] < 0) {
        depth[*v] = depth[u] + 1;
        owner[*v] = owner[u];
        odd[owner[u]] += depth[*v] & 1;
        queue.push_back(*v);
      }
    }
  }
  // Keep odd only when it is non-empty and strictly smaller than even.
  std::vector<uint8_t> keep_odd(clusters.count);
  for (int64_t c = 0; c < clusters.count; ++c) {
    const int64_t even = clusters.size(c) - odd[c];
    keep_odd[c] = odd[c] > 0 && odd[c] < even;
  }
  std::vector<int64_t> pooled;
  pooled.reserve(n / 2 + clusters.count);
  for (int64_t v = 0; v < n; ++v) {
    if ((depth[v] & 1) == keep_odd[owner[v]]) pooled.push_back(v);
  }
  return pooled;
}

CsrGraph enhance_adjacency(const CsrGraph& graph, const std::vector<int64_t>& pooled) {
  const int64_t n = graph.num_nodes;
  const int64_t m = static_cast<int64_t>(pooled.size());
  std::vector<int64_t> new_index(n, -1);
  for (int64_t r = 0; r < m; ++r) new_index[pooled[r]] = r;

  // Rows are built in fixed chunks (independent of the thread count), then concatenated.
  constexpr int64_t kChunk = 4096;
  const int64_t num_chunks = (m + kChunk - 1) / kChunk;
  std::vector<std::vector<int64_t>> chunk_targets(num_chunks);
  CsrGraph out;
  out.num_nodes = m;
  out.offsets.assign(m + 1, 0);
#pragma omp parallel if (num_chunks > 1)
  {
    std::vector<int64_t> mark(n, -1);  // mark[v] == r: v already seen for row r
#pragma omp for schedule(dynamic, 1)
    for (int64_t chunk = 0; chunk < num_chunks; ++chunk) {
      std::vector<int64_t>& targets = chunk_targets[chunk];
      const int64_t row_end = std::min(m, (chunk + 1) * kChunk);
      for (int64_t r = chunk * kChunk; r < row_end; ++r) {
        const int64_t u = pooled[r];
        const size_t start = targets.size();
        mark[u] = r;
        for (const int64_t* v = graph.begin(u); v != graph.end(u); ++v) {
          if (mark[*v] != r) {
            mark[*v] = r;
            if (new_index[*v] >= 0) targets.push_back(new_index[*v]);
          }
          for (const int64_t* w = graph.begin(*v); w != graph.end(*v); ++w) {
            if (mark[*w] != r) {
              mark[*w] = r;
              if (new_index[*w] >= 0) targets.push_back(new_index[*w]);
            }
          }
        }
        std::sort(targets.begin() + start, targets.end());
        out.offsets[r + 1] = static_cast<int64_t>(targets.size() - start);
      }
    }
  }
  for (int64_t r = 0; r < m; ++r) out.offsets[r + 1] += out.offsets[r];
  out.targets.resize(out.offsets[m]);
#pragma omp parallel for schedule(dynamic, 1) if (num_chunks > 1)
  for (int64_t chunk = 0; chunk < num_chunks; ++chunk) {
    std::copy(chunk_targets[chunk].begin(), chunk_targets[chunk].end(),
              out.targets.begin() + out.offsets[chunk * kChunk]);
    std::vector<int64_t>().swap(chunk_targets[chunk]);
  }
  return out;
}

TransitionWeights transition_weights(const CsrGraph& graph, const std::vector<double>& node_weight,
                                     const std::vector<int64_t>& pooled) {
  const int64_t n = graph.num_nodes;
  std::vector<double> spread(n);    // ŵ_i. = w_i / outdeg(i), the same on every out-edge of i
  std::vector<double> incoming(n);  // sum_{i->j} ŵ_ij
#pragma omp parallel for schedule(static) if (n > kParallelNodes)
  for (int64_t i = 0; i < n; ++i) {
    const int64_t degree = graph.degree(i);
    spread[i] = degree > 0 ? node_weight[i] / static_cast<double>(degree) : 0.0;
  }
  // The graph is symmetric: in-neighbours of j are its neighbours, summed in ascending order.
#pragma omp parallel for schedule(static) if (n > kParallelNodes)
  for (int64_t j = 0; j < n; ++j) {
    double sum = 0.0;
    for (const int64_t* i = graph.begin(j); i != graph.end(j); ++i) sum += spread[*i];
    incoming[j] = sum;
  }
  TransitionWeights out;
  out.down_weight.resize(graph.num_edges());
#pragma omp parallel for schedule(static) if (n > kParallelNodes)
  for (int64_t i = 0; i < n; ++i) {
    for (int64_t e = graph.offsets[i]; e < graph.offsets[i + 1]; ++e) {
      out.down_weight[e] = static_cast<float>(spread[i] / incoming[graph.targets[e]]);
    }
  }
  out.node_weight.resize(pooled.size());
  for (size_t r = 0; r < pooled.size(); ++r) {
    const int64_t j = pooled[r];
    out.node_weight[r] = graph.degree(j) > 0 ? incoming[j] : node_weight[j];
  }
  return out;
}

}  // namespace bsms
