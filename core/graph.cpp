#include "core/graph.hpp"

#include <algorithm>
#include <deque>

#include "core/error.hpp"

namespace bsms {

EdgeList CsrGraph::edges() const {
  EdgeList list;
  list.data.resize(2 * targets.size());
  for (int64_t i = 0; i < num_nodes; ++i) {
    for (int64_t e = offsets[i]; e < offsets[i + 1]; ++e) {
      list.data[2 * e] = i;
      list.data[2 * e + 1] = targets[e];
    }
  }
  return list;
}

CsrGraph graph_from_pairs(int64_t num_nodes, const std::vector<int64_t>& pairs) {
  if (pairs.size() % 2 != 0) throw std::invalid_argument("graph_from_pairs: odd pair array");
  CsrGraph g;
  g.num_nodes = num_nodes;
  // Counting sort by sender (both directions), then sort + unique each row.
  std::vector<int64_t> count(num_nodes + 1, 0);
  const size_t num_pairs = pairs.size() / 2;
  for (size_t p = 0; p < num_pairs; ++p) {
    const int64_t a = pairs[2 * p], b = pairs[2 * p + 1];
    if (a < 0 || b < 0 || a >= num_nodes || b >= num_nodes)
      throw std::out_of_range("graph_from_pairs: node index out of range");
    if (a == b) continue;
    ++count[a + 1];
    ++count[b + 1];
  }
  for (int64_t i = 0; i < num_nodes; ++i) count[i + 1] += count[i];
  std::vector<int64_t> adj(count[num_nodes]);
  std::vector<int64_t> fill(count.begin(), count.end() - 1);
  for (size_t p = 0; p < num_pairs; ++p) {
    const int64_t a = pairs[2 * p], b = pairs[2 * p + 1];
    if (a == b) continue;
    adj[fill[a]++] = b;
    adj[fill[b]++] = a;
  }
  g.offsets.assign(num_nodes + 1, 0);
  std::vector<int64_t> row_size(num_nodes, 0);
#pragma omp parallel for schedule(dynamic, 1024)
  for (int64_t i = 0; i < num_nodes; ++i) {
    auto first = adj.begin() + count[i], last = adj.begin() + count[i + 1];
    std::sort(first, last);
    row_size[i] = std::unique(first, last) - first;
  }
  for (int64_t i = 0; i < num_nodes; ++i) g.offsets[i + 1] = g.offsets[i] + row_size[i];
  g.targets.resize(g.offsets[num_nodes]);
#pragma omp parallel for schedule(dynamic, 1024)
  for (int64_t i = 0; i < num_nodes; ++i) {
    std::copy(adj.begin() + count[i], adj.begin() + count[i] + row_size[i],
              g.targets.begin() + g.offsets[i]);
  }
  return g;
}

CsrGraph mesh_graph(const Mesh& mesh) {
  const int k = mesh.nodes_per_cell();
  const int64_t c = mesh.num_cells();
  std::vector<int64_t> pairs;
  pairs.reserve(static_cast<size_t>(c) * k * (k - 1));
  for (int64_t cell = 0; cell < c; ++cell) {
    for (int a = 0; a < k; ++a) {
      for (int b = a + 1; b < k; ++b) {
        pairs.push_back(mesh.cells(cell, a));
        pairs.push_back(mesh.cells(cell, b));
      }
    }
  }
  return graph_from_pairs(mesh.num_nodes(), pairs);
}

Components connected_components(const CsrGraph& graph) {
  Components comp;
  comp.label.assign(graph.num_nodes, -1);
  std::vector<int64_t> stack;
  for (int64_t s = 0; s < graph.num_nodes; ++s) {
    if (comp.label[s] != -1) continue;
    const int64_t id = comp.count++;
    comp.label[s] = id;
    stack.push_back(s);
    while (!stack.empty()) {
      const int64_t u = stack.back();
      stack.pop_back();
      for (const int64_t* v = graph.begin(u); v != graph.end(u); ++v) {
        if (comp.label[*v] == -1) {
          comp.label[*v] = id;
          stack.push_back(*v);
        }
      }
    }
  }
  return comp;
}

std::vector<int64_t> bfs_depths(const CsrGraph& graph, int64_t source) {
  std::vector<int64_t> depth(graph.num_nodes, kUnreached);
  if (source < 0 || source >= graph.num_nodes) throw std::out_of_range("bfs_depths: bad source");
  std::vector<int64_t> queue;
  queue.reserve(graph.num_nodes);
  depth[source] = 0;
  queue.push_back(source);
  for (size_t head = 0; head < queue.size(); ++head) {
    const int64_t u = queue[head];
    for (const int64_t* v = graph.begin(u); v != graph.end(u); ++v) {
      if (depth[*v] == kUnreached) {
        depth[*v] = depth[u] + 1;
        queue.push_back(*v);
      }
    }
  }
  return depth;
}

}  // namespace bsms
