#include "preprocess/edge_thinning.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <tuple>

#include "core/error.hpp"

namespace bsms {

namespace {

constexpr int64_t kParallelNodes = 16384;
constexpr int kMaxCones = 14;

struct Cones {
  int count = 0;
  std::array<std::array<double, 3>, kMaxCones> direction{};
};

Cones make_cones(int dim) {
  Cones cones;
  if (dim == 1) {
    cones.direction[0] = {1, 0, 0};
    cones.direction[1] = {-1, 0, 0};
    cones.count = 2;
  } else if (dim == 2) {
    for (int s = 0; s < 8; ++s) {
      const double angle = M_PI / 4.0 * s;
      cones.direction[s] = {std::cos(angle), std::sin(angle), 0};
    }
    cones.count = 8;
  } else {
    int s = 0;
    for (int axis = 0; axis < 3; ++axis) {
      for (double sign : {1.0, -1.0}) {
        cones.direction[s] = {0, 0, 0};
        cones.direction[s][axis] = sign;
        ++s;
      }
    }
    const double c = 1.0 / std::sqrt(3.0);
    for (double x : {c, -c})
      for (double y : {c, -c})
        for (double z : {c, -c}) cones.direction[s++] = {x, y, z};
    cones.count = s;
  }
  return cones;
}

double squared_distance(const RowMatrixXd& positions, int64_t a, int64_t b) {
  double sum = 0.0;
  for (Eigen::Index c = 0; c < positions.cols(); ++c) {
    const double d = positions(b, c) - positions(a, c);
    sum += d * d;
  }
  return sum;
}

// Position of the edge j -> i in j's sorted row.
int64_t reverse_edge(const CsrGraph& graph, int64_t i, int64_t j) {
  const int64_t* at = std::lower_bound(graph.begin(j), graph.end(j), i);
  return at - graph.targets.data();
}

int64_t find_root(std::vector<int64_t>& parent, int64_t x) {
  while (parent[x] != x) {
    parent[x] = parent[parent[x]];
    x = parent[x];
  }
  return x;
}

// chosen[e] = 1 where node e's sender keeps edge e: all its edges up to a degree of 2 cones,
// else the nearest and the farthest neighbour in each cone. Returns the number of thinned nodes.
int64_t choose_edges(const CsrGraph& graph, const RowMatrixXd& positions, const Cones& cones,
                     std::vector<uint8_t>& chosen) {
  const int64_t n = graph.num_nodes;
  const int dim = static_cast<int>(positions.cols());
  const int64_t limit = 2 * static_cast<int64_t>(cones.count);
  int64_t thinned = 0;
#pragma omp parallel for schedule(dynamic, 256) reduction(+ : thinned) if (n > kParallelNodes)
  for (int64_t i = 0; i < n; ++i) {
    const int64_t first = graph.offsets[i], last = graph.offsets[i + 1];
    if (last - first <= limit) {
      std::fill(chosen.begin() + first, chosen.begin() + last, 1);
      continue;
    }
    ++thinned;
    std::array<int64_t, kMaxCones> nearest, farthest;
    std::array<double, kMaxCones> near_d, far_d;
    nearest.fill(-1);
    farthest.fill(-1);
    for (int64_t e = first; e < last; ++e) {
      const int64_t j = graph.targets[e];
      std::array<double, 3> d{0, 0, 0};
      for (int c = 0; c < dim; ++c) d[c] = positions(j, c) - positions(i, c);
      int best = 0;
      double best_dot = -std::numeric_limits<double>::infinity();
      for (int s = 0; s < cones.count; ++s) {
        const auto& u = cones.direction[s];
        const double dot = d[0] * u[0] + d[1] * u[1] + d[2] * u[2];
        if (dot > best_dot) {
          best_dot = dot;
          best = s;
        }
      }
      const double length = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
      // Rows are sorted, so strict comparisons break ties towards the lower neighbour index.
      if (nearest[best] < 0 || length < near_d[best]) {
        nearest[best] = e;
        near_d[best] = length;
      }
      if (farthest[best] < 0 || length > far_d[best]) {
        farthest[best] = e;
        far_d[best] = length;
      }
    }
    for (int s = 0; s < cones.count; ++s) {
      if (nearest[s] >= 0) chosen[nearest[s]] = 1;
      if (farthest[s] >= 0) chosen[farthest[s]] = 1;
    }
  }
  return thinned;
}

// keep[e]: either end chose the edge.
std::vector<uint8_t> keep_either_end(const CsrGraph& graph, const std::vector<uint8_t>& chosen) {
  const int64_t n = graph.num_nodes;
  std::vector<uint8_t> keep(graph.targets.size(), 0);
#pragma omp parallel for schedule(dynamic, 256) if (n > kParallelNodes)
  for (int64_t i = 0; i < n; ++i) {
    for (int64_t e = graph.offsets[i]; e < graph.offsets[i + 1]; ++e) {
      keep[e] = chosen[e] || chosen[reverse_edge(graph, i, graph.targets[e])];
    }
  }
  return keep;
}

// Clusters must not split: puts back the shortest removed edges joining parts (Kruskal).
// Returns the number of directed edges put back.
int64_t reconnect_clusters(const CsrGraph& graph, const RowMatrixXd& positions,
                           std::vector<uint8_t>& keep) {
  const int64_t n = graph.num_nodes;
  int64_t restored = 0;
  std::vector<int64_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  for (int64_t i = 0; i < n; ++i) {
    for (int64_t e = graph.offsets[i]; e < graph.offsets[i + 1]; ++e) {
      const int64_t j = graph.targets[e];
      if (keep[e] && j > i) {
        const int64_t a = find_root(parent, i), b = find_root(parent, j);
        if (a != b) parent[std::max(a, b)] = std::min(a, b);
      }
    }
  }
  std::vector<std::tuple<double, int64_t, int64_t>> removed;  // (length², i, edge)
  for (int64_t i = 0; i < n; ++i) {
    for (int64_t e = graph.offsets[i]; e < graph.offsets[i + 1]; ++e) {
      const int64_t j = graph.targets[e];
      if (!keep[e] && j > i && find_root(parent, i) != find_root(parent, j)) {
        removed.emplace_back(squared_distance(positions, i, j), i, e);
      }
    }
  }
  std::sort(removed.begin(), removed.end());
  for (const auto& [length, i, e] : removed) {
    const int64_t j = graph.targets[e];
    const int64_t a = find_root(parent, i), b = find_root(parent, j);
    if (a == b) continue;
    parent[std::max(a, b)] = std::min(a, b);
    keep[e] = 1;
    keep[reverse_edge(graph, i, j)] = 1;
    restored += 2;
  }
  return restored;
}

// The edges of `graph` with keep[e] set.
CsrGraph kept_edges(const CsrGraph& graph, const std::vector<uint8_t>& keep) {
  const int64_t n = graph.num_nodes;
  CsrGraph out;
  out.num_nodes = n;
  out.offsets.assign(n + 1, 0);
  for (int64_t i = 0; i < n; ++i) {
    int64_t count = 0;
    for (int64_t e = graph.offsets[i]; e < graph.offsets[i + 1]; ++e) count += keep[e];
    out.offsets[i + 1] = out.offsets[i] + count;
  }
  out.targets.resize(out.offsets[n]);
#pragma omp parallel for schedule(static) if (n > kParallelNodes)
  for (int64_t i = 0; i < n; ++i) {
    int64_t at = out.offsets[i];
    for (int64_t e = graph.offsets[i]; e < graph.offsets[i + 1]; ++e) {
      if (keep[e]) out.targets[at++] = graph.targets[e];
    }
  }
  return out;
}

}  // namespace

int thinning_cones(int dim) {
  if (dim < 1 || dim > 3) throw InputError("edge thinning: positions must have 1 to 3 columns");
  return make_cones(dim).count;
}

CsrGraph thin_adjacency(const CsrGraph& graph, const RowMatrixXd& positions,
                        ThinningReport* report) {
  const int64_t n = graph.num_nodes;
  const int dim = static_cast<int>(positions.cols());
  if (positions.rows() != n) {
    throw InputError("edge thinning needs positions for all " + std::to_string(n) + " nodes, got " +
                     std::to_string(positions.rows()));
  }
  thinning_cones(dim);  // checks dim
  const Cones cones = make_cones(dim);
  std::vector<uint8_t> chosen(graph.targets.size(), 0);
  const int64_t thinned = choose_edges(graph, positions, cones, chosen);
  std::vector<uint8_t> keep = keep_either_end(graph, chosen);
  const int64_t restored = reconnect_clusters(graph, positions, keep);
  CsrGraph out = kept_edges(graph, keep);
  if (report != nullptr) {
    report->thinned_nodes = thinned;
    report->restored_edges = restored;
  }
  return out;
}

}  // namespace bsms
