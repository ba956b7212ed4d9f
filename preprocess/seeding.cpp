#include "preprocess/seeding.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <limits>

#include "core/error.hpp"
#include "core/hash.hpp"

namespace bsms {

ClusterNodes group_clusters(const Components& components) {
  ClusterNodes out;
  out.count = components.count;
  out.offsets.assign(static_cast<size_t>(out.count) + 1, 0);
  for (int64_t label : components.label) ++out.offsets[label + 1];
  for (int64_t c = 0; c < out.count; ++c) out.offsets[c + 1] += out.offsets[c];
  out.nodes.resize(components.label.size());
  std::vector<int64_t> next(out.offsets.begin(), out.offsets.end() - 1);
  for (size_t i = 0; i < components.label.size(); ++i) {
    out.nodes[next[components.label[i]]++] = static_cast<int64_t>(i);
  }
  return out;
}

std::vector<int64_t> close_center_seeds(const ClusterNodes& clusters,
                                        const RowMatrixXd& positions) {
  const int64_t dim = positions.cols();
  std::vector<int64_t> seeds(clusters.count);
  std::vector<double> mean(dim);
#pragma omp parallel for schedule(dynamic, 64) firstprivate(mean) if (clusters.count > 64)
  for (int64_t c = 0; c < clusters.count; ++c) {
    std::fill(mean.begin(), mean.end(), 0.0);
    for (const int64_t* it = clusters.begin(c); it != clusters.end(c); ++it) {
      for (int64_t d = 0; d < dim; ++d) mean[d] += positions(*it, d);
    }
    const double n = static_cast<double>(clusters.size(c));
    for (int64_t d = 0; d < dim; ++d) mean[d] /= n;
    double best = std::numeric_limits<double>::infinity();
    int64_t best_node = *clusters.begin(c);
    for (const int64_t* it = clusters.begin(c); it != clusters.end(c); ++it) {
      double dist2 = 0.0;
      for (int64_t d = 0; d < dim; ++d) {
        const double delta = positions(*it, d) - mean[d];
        dist2 += delta * delta;
      }
      if (dist2 < best) {
        best = dist2;
        best_node = *it;
      }
    }
    seeds[c] = best_node;
  }
  return seeds;
}

namespace {

constexpr int kWordBits = 64;
constexpr int64_t kNoSum = -1;

// Best (sum, node) so far; a candidate is excluded when it cannot beat it, ties going to the
// lower node index.
struct Best {
  int64_t sum = std::numeric_limits<int64_t>::max();
  int64_t node = std::numeric_limits<int64_t>::max();
  bool excludes(int64_t lower_bound, int64_t candidate) const {
    return lower_bound > sum || (lower_bound == sum && candidate > node);
  }
  void offer(int64_t candidate_sum, int64_t candidate) {
    if (candidate_sum < sum || (candidate_sum == sum && candidate < node)) {
      sum = candidate_sum;
      node = candidate;
    }
  }
};

// 64 counters updated in parallel: plane k holds bit k of every counter (carry-save adder).
class BitSlicedCounter {
 public:
  void add(uint64_t bits) {
    int k = 0;
    while (bits != 0) {
      const uint64_t carry = planes_[k] & bits;
      planes_[k] ^= bits;
      bits = carry;
      ++k;
    }
    top_ = std::max(top_, k);
  }
  // Adds every counter to counts[bit] and resets.
  void drain(int64_t* counts) {
    for (int k = 0; k < top_; ++k) {
      uint64_t word = planes_[k];
      while (word != 0) {
        counts[__builtin_ctzll(word)] += int64_t{1} << k;
        word &= word - 1;
      }
      planes_[k] = 0;
    }
    top_ = 0;
  }

 private:
  std::array<uint64_t, kWordBits + 1> planes_{};
  int top_ = 0;
};

// Per-thread scratch indexed by global node; every array is left all-zero / all-unset on return.
struct BfsWorkspace {
  explicit BfsWorkspace(int64_t num_nodes)
      : visited(num_nodes, 0), frontier(num_nodes, 0), next(num_nodes, 0), depth(num_nodes, -1) {}
  std::vector<uint64_t> visited, frontier, next;
  std::vector<int32_t> depth;
  std::vector<int64_t> current, upcoming, touched;
};

// Bit-parallel BFS from up to 64 distinct sources of one cluster of `cluster_size` nodes. Writes
// the exact distance sum of each source to sums[b], or kNoSum where the source was dropped because
// its bound sum(settled) + (unsettled nodes) * (depth + 1) was excluded by `cutoff`.
void bit_parallel_sums(const CsrGraph& graph, const int64_t* sources, int count,
                       int64_t cluster_size, const Best& cutoff, BfsWorkspace& ws, int64_t* sums) {
  uint64_t alive = count == kWordBits ? ~uint64_t{0} : ((uint64_t{1} << count) - 1);
  std::array<int64_t, kWordBits> reached{}, partial{}, counts{};
  ws.current.clear();
  ws.touched.clear();
  for (int b = 0; b < count; ++b) {
    const int64_t s = sources[b];
    if (ws.visited[s] == 0) {
      ws.touched.push_back(s);
      ws.current.push_back(s);
    }
    ws.visited[s] |= uint64_t{1} << b;
    ws.frontier[s] |= uint64_t{1} << b;
    reached[b] = 1;
    sums[b] = kNoSum;
    if (cluster_size == 1) {
      sums[b] = 0;
      alive &= ~(uint64_t{1} << b);
    }
  }
  BitSlicedCounter counter;
  for (int64_t depth = 1; alive != 0 && !ws.current.empty(); ++depth) {
    ws.upcoming.clear();
    for (int64_t u : ws.current) {
      const uint64_t bits = ws.frontier[u];
      for (const int64_t* v = graph.begin(u); v != graph.end(u); ++v) {
        const uint64_t fresh = bits & ~ws.visited[*v];
        if (fresh != 0) {
          if (ws.next[*v] == 0) ws.upcoming.push_back(*v);
          ws.next[*v] |= fresh;
        }
      }
    }
    for (int64_t u : ws.current) ws.frontier[u] = 0;
    ws.current.clear();
    for (int64_t v : ws.upcoming) {
      const uint64_t fresh = ws.next[v] & alive;
      ws.next[v] = 0;
      if (fresh == 0) continue;
      if (ws.visited[v] == 0) ws.touched.push_back(v);
      ws.visited[v] |= fresh;
      ws.frontier[v] = fresh;
      ws.current.push_back(v);
      counter.add(fresh);
    }
    counts.fill(0);
    counter.drain(counts.data());
    for (uint64_t live = alive; live != 0; live &= live - 1) {
      const int b = __builtin_ctzll(live);
      reached[b] += counts[b];
      partial[b] += depth * counts[b];
      if (reached[b] == cluster_size) {
        sums[b] = partial[b];
        alive &= ~(uint64_t{1} << b);
      } else if (cutoff.excludes(partial[b] + (cluster_size - reached[b]) * (depth + 1),
                                 sources[b])) {
        alive &= ~(uint64_t{1} << b);
      }
    }
  }
  for (int64_t v : ws.touched) {
    ws.visited[v] = 0;
    ws.frontier[v] = 0;
  }
}

// Exact MinAve of a small cluster: every node evaluated, 64 per pass.
int64_t min_ave_small(const CsrGraph& graph, const int64_t* nodes, int64_t n, BfsWorkspace& ws,
                      MinAveStats& stats) {
  Best best;
  std::array<int64_t, kWordBits> sums{};
  for (int64_t start = 0; start < n; start += kWordBits) {
    const int count = static_cast<int>(std::min<int64_t>(kWordBits, n - start));
    bit_parallel_sums(graph, nodes + start, count, n, best, ws, sums.data());
    for (int b = 0; b < count; ++b) {
      if (sums[b] != kNoSum) best.offer(sums[b], nodes[start + b]);
    }
    stats.evaluated += count;
    ++stats.batches;
  }
  return best.node;
}

// Compact groups of about `blob_size` nodes: BFS-grown over not-yet-assigned nodes, started from
// nodes in BFS order of the cluster so consecutive blobs are neighbours.
std::vector<std::vector<int64_t>> make_blobs(const CsrGraph& graph, const int64_t* nodes, int64_t n,
                                             int64_t blob_size, std::vector<int64_t>& stamp) {
  // BFS order of the cluster from its first node (stamp -2 = ordered).
  std::vector<int64_t> order;
  order.reserve(n);
  order.push_back(nodes[0]);
  stamp[nodes[0]] = -2;
  for (size_t head = 0; head < order.size(); ++head) {
    for (const int64_t* v = graph.begin(order[head]); v != graph.end(order[head]); ++v) {
      if (stamp[*v] != -2) {
        stamp[*v] = -2;
        order.push_back(*v);
      }
    }
  }
  std::vector<std::vector<int64_t>> blobs;
  std::vector<int64_t> queue;
  for (int64_t start : order) {
    if (stamp[start] >= 0) continue;  // already in a blob
    const int64_t id = static_cast<int64_t>(blobs.size());
    std::vector<int64_t> blob;
    queue.clear();
    queue.push_back(start);
    stamp[start] = n + id;  // queued for this blob
    for (size_t head = 0; head < queue.size() && static_cast<int64_t>(blob.size()) < blob_size;
         ++head) {
      const int64_t u = queue[head];
      blob.push_back(u);
      stamp[u] = id;
      for (const int64_t* v = graph.begin(u); v != graph.end(u); ++v) {
        if (stamp[*v] == -2) {
          stamp[*v] = n + id;
          queue.push_back(*v);
        }
      }
    }
    for (int64_t v : queue) {
      if (stamp[v] == n + id) stamp[v] = -2;  // queued but not taken: free again
    }
    std::sort(blob.begin(), blob.end());
    blobs.push_back(std::move(blob));
  }
  for (int64_t i = 0; i < n; ++i) stamp[nodes[i]] = -1;
  return blobs;
}

// bound[i] = sum_B |B| d(nodes[i], B) <= sum of distances of nodes[i], one multi-source BFS per
// blob. Leaves local[nodes[i]] = i.
std::vector<int64_t> blob_lower_bounds(const CsrGraph& graph, const int64_t* nodes, int64_t n,
                                       std::vector<BfsWorkspace>& workspaces,
                                       std::vector<int64_t>& local,
                                       std::vector<std::vector<int64_t>>& blobs) {
  for (int64_t i = 0; i < n; ++i) local[nodes[i]] = i;
  const int64_t blob_size = std::max<int64_t>(kWordBits, (n + 1023) / 1024);
  blobs = make_blobs(graph, nodes, n, blob_size, local);
  for (int64_t i = 0; i < n; ++i) local[nodes[i]] = i;
  const int64_t num_blobs = static_cast<int64_t>(blobs.size());

  const int threads = static_cast<int>(workspaces.size());
  std::vector<std::vector<int64_t>> partial_bounds(threads);
#pragma omp parallel num_threads(threads) if (num_blobs > 1)
  {
    const int t = omp_get_thread_num();
    BfsWorkspace& ws = workspaces[t];
    std::vector<int64_t>& acc = partial_bounds[t];
    acc.assign(n, 0);
    std::vector<int64_t>& queue = ws.touched;
#pragma omp for schedule(dynamic, 4)
    for (int64_t b = 0; b < num_blobs; ++b) {
      const int64_t weight = static_cast<int64_t>(blobs[b].size());
      queue.clear();
      for (int64_t s : blobs[b]) {
        ws.depth[s] = 0;
        queue.push_back(s);
      }
      for (size_t head = 0; head < queue.size(); ++head) {
        const int64_t u = queue[head];
        const int32_t next_depth = ws.depth[u] + 1;
        for (const int64_t* v = graph.begin(u); v != graph.end(u); ++v) {
          if (ws.depth[*v] < 0) {
            ws.depth[*v] = next_depth;
            queue.push_back(*v);
          }
        }
        acc[local[u]] += weight * ws.depth[u];
      }
      for (int64_t v : queue) ws.depth[v] = -1;
    }
    queue.clear();
  }
  std::vector<int64_t> bound(n, 0);
  for (const auto& acc : partial_bounds) {
    if (acc.empty()) continue;  // thread not started (serial region)
    for (int64_t i = 0; i < n; ++i) bound[i] += acc[i];
  }
  return bound;
}

int64_t min_ave_large(const CsrGraph& graph, const int64_t* nodes, int64_t n,
                      std::vector<BfsWorkspace>& workspaces, std::vector<int64_t>& local,
                      MinAveStats& stats) {
  std::vector<std::vector<int64_t>> blobs;
  const std::vector<int64_t> bound = blob_lower_bounds(graph, nodes, n, workspaces, local, blobs);
  const int64_t num_blobs = static_cast<int64_t>(blobs.size());
  const int threads = static_cast<int>(workspaces.size());
  stats.bound_bfs += num_blobs;

  Best best;
  std::vector<std::array<int64_t, kWordBits>> pass_sums;
  auto evaluate = [&](const std::vector<std::vector<int64_t>>& passes) {
    pass_sums.resize(passes.size());
    const Best cutoff = best;
    const int64_t num_passes = static_cast<int64_t>(passes.size());
#pragma omp parallel for num_threads(threads) schedule(dynamic, 1) if (num_passes > 1)
    for (int64_t p = 0; p < num_passes; ++p) {
      bit_parallel_sums(graph, passes[p].data(), static_cast<int>(passes[p].size()), n, cutoff,
                        workspaces[omp_get_thread_num()], pass_sums[p].data());
    }
    for (int64_t p = 0; p < num_passes; ++p) {
      for (size_t b = 0; b < passes[p].size(); ++b) {
        if (pass_sums[p][b] != kNoSum) best.offer(pass_sums[p][b], passes[p][b]);
      }
      stats.evaluated += static_cast<int64_t>(passes[p].size());
      ++stats.batches;
    }
  };

  // Candidates by (bound, node). The first pass takes the 64 most promising (a compact group: the
  // bound varies smoothly) and gives a good best sum to prune with.
  std::vector<int64_t> order(n);
  for (int64_t i = 0; i < n; ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](int64_t a, int64_t b) {
    return std::make_pair(bound[a], nodes[a]) < std::make_pair(bound[b], nodes[b]);
  });
  std::vector<uint8_t> done(n, 0);
  {
    std::vector<int64_t> first;
    for (int64_t k = 0; k < n && k < kWordBits; ++k) {
      first.push_back(nodes[order[k]]);
      done[order[k]] = 1;
    }
    evaluate({first});
  }
  // The remaining candidates, grouped 64 at a time by BFS inside the candidate set (compact
  // groups keep the bit-parallel BFS fronts narrow), groups in order of their best member.
  std::vector<int64_t> group_of(n, -1);  // -1: not a candidate, -2: candidate not yet grouped
  for (int64_t k = 0; k < n; ++k) {
    const int64_t i = order[k];
    if (best.excludes(bound[i], nodes[i])) break;
    if (!done[i]) group_of[i] = -2;
  }
  std::vector<std::vector<int64_t>> groups;
  std::vector<int64_t> queue;
  for (int64_t k = 0; k < n; ++k) {
    const int64_t start = order[k];
    if (group_of[start] != -2) continue;
    const int64_t id = static_cast<int64_t>(groups.size());
    groups.emplace_back();
    queue.assign(1, start);
    group_of[start] = n + id;  // queued
    for (size_t head = 0; head < queue.size() && groups[id].size() < kWordBits; ++head) {
      const int64_t i = queue[head];
      groups[id].push_back(nodes[i]);
      group_of[i] = id;
      for (const int64_t* v = graph.begin(nodes[i]); v != graph.end(nodes[i]); ++v) {
        if (group_of[local[*v]] == -2) {
          group_of[local[*v]] = n + id;
          queue.push_back(local[*v]);
        }
      }
    }
    for (int64_t i : queue) {
      if (group_of[i] == n + id) group_of[i] = -2;  // queued, not taken
    }
  }
  std::vector<std::vector<int64_t>> passes;
  for (size_t next = 0; next < groups.size();) {
    passes.clear();
    for (; next < groups.size() && static_cast<int>(passes.size()) < 2 * threads; ++next) {
      std::vector<int64_t> pass;
      for (int64_t v : groups[next]) {
        if (!best.excludes(bound[local[v]], v)) pass.push_back(v);
      }
      if (!pass.empty()) passes.push_back(std::move(pass));
    }
    evaluate(passes);
  }
  stats.pruned += n - stats.evaluated;
  return best.node;
}

}  // namespace

std::vector<int64_t> min_ave_seeds(const CsrGraph& graph, const ClusterNodes& clusters,
                                   MinAveStats* stats) {
  constexpr int64_t kSmallCluster = 4 * kWordBits;
  const int threads = std::max(1, omp_get_max_threads());
  std::vector<int64_t> seeds(clusters.count, -1);
  MinAveStats total;
  std::vector<BfsWorkspace> workspaces;
  workspaces.reserve(threads);
  for (int t = 0; t < threads; ++t) workspaces.emplace_back(graph.num_nodes);

  // Small clusters, in parallel over clusters.
  std::vector<MinAveStats> thread_stats(threads);
#pragma omp parallel for num_threads(threads) schedule(dynamic, 16) if (clusters.count > 16)
  for (int64_t c = 0; c < clusters.count; ++c) {
    const int64_t n = clusters.size(c);
    if (n <= 2) {
      seeds[c] = *clusters.begin(c);  // equal sums: the lowest index
    } else if (n <= kSmallCluster) {
      const int t = omp_get_thread_num();
      seeds[c] = min_ave_small(graph, clusters.begin(c), n, workspaces[t], thread_stats[t]);
    }
  }
  for (const auto& s : thread_stats) {
    total.evaluated += s.evaluated;
    total.batches += s.batches;
  }
  // Large clusters one at a time, parallel inside.
  std::vector<int64_t> local(graph.num_nodes, -1);
  for (int64_t c = 0; c < clusters.count; ++c) {
    if (clusters.size(c) <= kSmallCluster) continue;
    MinAveStats cluster_stats;
    seeds[c] =
        min_ave_large(graph, clusters.begin(c), clusters.size(c), workspaces, local, cluster_stats);
    total.bound_bfs += cluster_stats.bound_bfs;
    total.evaluated += cluster_stats.evaluated;
    total.batches += cluster_stats.batches;
    total.pruned += cluster_stats.pruned;
  }
  if (stats != nullptr) *stats = total;
  return seeds;
}

std::vector<int64_t> distance_sums(const CsrGraph& graph, const std::vector<int64_t>& sources,
                                   int64_t cluster_size) {
  if (sources.size() > static_cast<size_t>(kWordBits)) {
    throw InputError("distance_sums: at most 64 sources per call, got " +
                     std::to_string(sources.size()));
  }
  BfsWorkspace ws(graph.num_nodes);
  std::array<int64_t, kWordBits> sums{};
  bit_parallel_sums(graph, sources.data(), static_cast<int>(sources.size()), cluster_size, Best{},
                    ws, sums.data());
  return std::vector<int64_t>(sums.begin(), sums.begin() + sources.size());
}

std::vector<int64_t> distance_sum_lower_bounds(const CsrGraph& graph,
                                               const std::vector<int64_t>& cluster_nodes) {
  std::vector<BfsWorkspace> workspaces;
  for (int t = 0; t < std::max(1, omp_get_max_threads()); ++t) {
    workspaces.emplace_back(graph.num_nodes);
  }
  std::vector<int64_t> local(graph.num_nodes, -1);
  std::vector<std::vector<int64_t>> blobs;
  return blob_lower_bounds(graph, cluster_nodes.data(), static_cast<int64_t>(cluster_nodes.size()),
                           workspaces, local, blobs);
}

std::vector<int64_t> random_seeds(const ClusterNodes& clusters, uint64_t rng_seed) {
  std::vector<int64_t> seeds(clusters.count);
  const uint64_t key = splitmix64(rng_seed);
  for (int64_t c = 0; c < clusters.count; ++c) {
    const uint64_t draw = splitmix64(key ^ splitmix64(static_cast<uint64_t>(c)));
    seeds[c] = clusters.begin(c)[draw % static_cast<uint64_t>(clusters.size(c))];
  }
  return seeds;
}

}  // namespace bsms
