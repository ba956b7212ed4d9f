#include "test_graphs.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>

namespace bsms::test {

namespace {

void add_cell_pairs(const std::vector<int64_t>& cell, std::vector<int64_t>& pairs) {
  for (size_t a = 0; a < cell.size(); ++a) {
    for (size_t b = a + 1; b < cell.size(); ++b) {
      pairs.push_back(cell[a]);
      pairs.push_back(cell[b]);
    }
  }
}

}  // namespace

TestGraph grid_triangles(int nx, int ny, double hole_fraction, double jitter,
                         std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto id = [&](int i, int j) { return static_cast<int64_t>(i) * (ny + 1) + j; };
  TestGraph out;
  out.name = "grid_triangles " + std::to_string(nx) + "x" + std::to_string(ny);
  const int64_t n = static_cast<int64_t>(nx + 1) * (ny + 1);
  out.positions.resize(n, 2);
  for (int i = 0; i <= nx; ++i) {
    for (int j = 0; j <= ny; ++j) {
      out.positions(id(i, j), 0) = i + jitter * (unit(rng) - 0.5);
      out.positions(id(i, j), 1) = j + jitter * (unit(rng) - 0.5);
    }
  }
  std::vector<int64_t> pairs;
  for (int i = 0; i < nx; ++i) {
    for (int j = 0; j < ny; ++j) {
      const bool flip = unit(rng) < 0.5;
      const int64_t a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
      const std::vector<std::vector<int64_t>> cells =
          flip ? std::vector<std::vector<int64_t>>{{a, b, c}, {a, c, d}}
               : std::vector<std::vector<int64_t>>{{a, b, d}, {b, c, d}};
      for (const auto& cell : cells) {
        if (unit(rng) >= hole_fraction) add_cell_pairs(cell, pairs);
      }
    }
  }
  out.graph = graph_from_pairs(n, pairs);
  return out;
}

TestGraph grid_tets(int nx, int ny, int nz, double hole_fraction, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto id = [&](int i, int j, int k) {
    return (static_cast<int64_t>(i) * (ny + 1) + j) * (nz + 1) + k;
  };
  TestGraph out;
  out.name =
      "grid_tets " + std::to_string(nx) + "x" + std::to_string(ny) + "x" + std::to_string(nz);
  const int64_t n = static_cast<int64_t>(nx + 1) * (ny + 1) * (nz + 1);
  out.positions.resize(n, 3);
  for (int i = 0; i <= nx; ++i) {
    for (int j = 0; j <= ny; ++j) {
      for (int k = 0; k <= nz; ++k) {
        out.positions.row(id(i, j, k)) << i + 0.2 * unit(rng), j + 0.2 * unit(rng),
            k + 0.2 * unit(rng);
      }
    }
  }
  std::vector<int64_t> pairs;
  std::array<int, 3> axes{0, 1, 2};
  for (int i = 0; i < nx; ++i) {
    for (int j = 0; j < ny; ++j) {
      for (int k = 0; k < nz; ++k) {
        std::sort(axes.begin(), axes.end());
        do {  // Kuhn subdivision: one tetrahedron per axis order
          if (unit(rng) < hole_fraction) continue;
          std::array<int, 3> corner{i, j, k};
          std::vector<int64_t> cell{id(i, j, k)};
          for (int axis : axes) {
            ++corner[axis];
            cell.push_back(id(corner[0], corner[1], corner[2]));
          }
          add_cell_pairs(cell, pairs);
        } while (std::next_permutation(axes.begin(), axes.end()));
      }
    }
  }
  out.graph = graph_from_pairs(n, pairs);
  return out;
}

TestGraph u_tunnel(int length, int width) {
  const int nx = 2 * width + 1, ny = length + width;
  auto id = [&](int i, int j) { return static_cast<int64_t>(i) * (ny + 1) + j; };
  TestGraph out;
  out.name = "u_tunnel " + std::to_string(length) + "x" + std::to_string(width);
  const int64_t n = static_cast<int64_t>(nx + 1) * (ny + 1);
  out.positions.resize(n, 2);
  for (int i = 0; i <= nx; ++i) {
    for (int j = 0; j <= ny; ++j) out.positions.row(id(i, j)) << i, j;
  }
  std::vector<int64_t> pairs;
  for (int i = 0; i < nx; ++i) {
    for (int j = 0; j < ny; ++j) {
      if (i == width && j >= width) continue;  // the gap between the arms
      add_cell_pairs({id(i, j), id(i + 1, j), id(i + 1, j + 1)}, pairs);
      add_cell_pairs({id(i, j), id(i + 1, j + 1), id(i, j + 1)}, pairs);
    }
  }
  out.graph = graph_from_pairs(n, pairs);
  return out;
}

TestGraph several_clusters(int clusters, int isolated, std::mt19937_64& rng) {
  std::uniform_int_distribution<int> side(1, 9);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<int64_t> pairs;
  std::vector<std::array<double, 2>> points;
  for (int c = 0; c < clusters; ++c) {
    TestGraph part = grid_triangles(side(rng), side(rng), 0.0, 0.3, rng);
    const int64_t base = static_cast<int64_t>(points.size());
    for (int64_t i = 0; i < part.graph.num_nodes; ++i) {
      points.push_back({part.positions(i, 0) + 20.0 * c, part.positions(i, 1)});
      for (const int64_t* j = part.graph.begin(i); j != part.graph.end(i); ++j) {
        pairs.push_back(base + i);
        pairs.push_back(base + *j);
      }
    }
  }
  for (int i = 0; i < isolated; ++i) points.push_back({100.0 * unit(rng), -5.0 * unit(rng)});
  const int64_t n = static_cast<int64_t>(points.size());
  std::vector<int64_t> permutation(n);
  std::iota(permutation.begin(), permutation.end(), 0);
  std::shuffle(permutation.begin(), permutation.end(), rng);
  for (auto& v : pairs) v = permutation[v];
  TestGraph out;
  out.name = "several_clusters " + std::to_string(clusters) + "+" + std::to_string(isolated);
  out.positions.resize(n, 2);
  for (int64_t i = 0; i < n; ++i) out.positions.row(permutation[i]) << points[i][0], points[i][1];
  out.graph = graph_from_pairs(n, pairs);
  return out;
}

TestGraph random_graph(int n, int degree, std::mt19937_64& rng) {
  std::uniform_int_distribution<int64_t> node(0, n - 1);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<int64_t> pairs;
  for (int64_t i = 0; i < n; ++i) {
    for (int d = 0; d < degree; ++d) {
      pairs.push_back(i);
      pairs.push_back(node(rng));
    }
  }
  TestGraph out;
  out.name = "random_graph " + std::to_string(n) + " deg " + std::to_string(degree);
  out.positions.resize(n, 2);
  for (int64_t i = 0; i < n; ++i) out.positions.row(i) << unit(rng), unit(rng);
  out.graph = graph_from_pairs(n, pairs);
  return out;
}

std::vector<TestGraph> random_test_graphs(int count, int max_nodes, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<TestGraph> out;
  const int side = std::max(2, static_cast<int>(std::sqrt(static_cast<double>(max_nodes))) - 1);
  const int cube = std::max(1, static_cast<int>(std::cbrt(static_cast<double>(max_nodes))) - 1);
  std::uniform_int_distribution<int> side_dist(1, side), cube_dist(1, cube);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int g = 0; g < count; ++g) {
    switch (g % 6) {
      case 0:
        out.push_back(grid_triangles(side_dist(rng), side_dist(rng), 0.0, 0.4, rng));
        break;
      case 1:
        out.push_back(grid_triangles(side_dist(rng), side_dist(rng), 0.35 * unit(rng), 0.4, rng));
        break;
      case 2:
        out.push_back(
            grid_tets(cube_dist(rng), cube_dist(rng), cube_dist(rng), 0.3 * unit(rng), rng));
        break;
      case 3: {
        const int width = 1 + static_cast<int>(unit(rng) * 3);
        out.push_back(u_tunnel(std::max(2, max_nodes / (8 * (width + 1)) - width), width));
        break;
      }
      case 4:
        out.push_back(several_clusters(1 + static_cast<int>(unit(rng) * 4),
                                       static_cast<int>(unit(rng) * 5), rng));
        break;
      default:
        out.push_back(random_graph(2 + static_cast<int>(unit(rng) * (max_nodes - 2)),
                                   1 + static_cast<int>(unit(rng) * 2), rng));
        break;
    }
    out.back().name += " #" + std::to_string(g);
  }
  return out;
}

std::vector<std::vector<int64_t>> all_pairs_depths(const CsrGraph& graph) {
  const int64_t n = graph.num_nodes;
  std::vector<std::vector<int64_t>> depth(n, std::vector<int64_t>(n, -1));
  for (int64_t s = 0; s < n; ++s) {
    std::vector<int64_t> queue{s};
    depth[s][s] = 0;
    for (size_t head = 0; head < queue.size(); ++head) {
      const int64_t u = queue[head];
      for (int64_t e = graph.offsets[u]; e < graph.offsets[u + 1]; ++e) {
        const int64_t v = graph.targets[e];
        if (depth[s][v] < 0) {
          depth[s][v] = depth[s][u] + 1;
          queue.push_back(v);
        }
      }
    }
  }
  return depth;
}

namespace {

// Cluster of each node = its lowest reachable node; clusters ordered by that node.
std::vector<std::vector<int64_t>> brute_clusters(const std::vector<std::vector<int64_t>>& depth) {
  const int64_t n = static_cast<int64_t>(depth.size());
  std::vector<std::vector<int64_t>> clusters;
  std::vector<int64_t> cluster_of(n, -1);
  for (int64_t v = 0; v < n; ++v) {
    int64_t lowest = v;
    for (int64_t u = 0; u < v; ++u) {
      if (depth[v][u] >= 0) {
        lowest = u;
        break;
      }
    }
    if (lowest == v) {
      cluster_of[v] = static_cast<int64_t>(clusters.size());
      clusters.push_back({});
    } else {
      cluster_of[v] = cluster_of[lowest];
    }
    clusters[cluster_of[v]].push_back(v);
  }
  return clusters;
}

}  // namespace

std::vector<int64_t> brute_min_ave_seeds(const CsrGraph& graph) {
  const auto depth = all_pairs_depths(graph);
  std::vector<int64_t> seeds;
  for (const auto& cluster : brute_clusters(depth)) {
    int64_t best = -1;
    double best_average = std::numeric_limits<double>::infinity();
    for (int64_t v : cluster) {
      int64_t sum = 0;
      for (int64_t u : cluster) sum += depth[v][u];
      const double average =
          cluster.size() > 1 ? static_cast<double>(sum) / static_cast<double>(cluster.size() - 1)
                             : 0.0;
      if (average < best_average) {
        best_average = average;
        best = v;
      }
    }
    seeds.push_back(best);
  }
  return seeds;
}

std::vector<int64_t> brute_close_center_seeds(const CsrGraph& graph, const RowMatrixXd& positions) {
  const auto depth = all_pairs_depths(graph);
  std::vector<int64_t> seeds;
  for (const auto& cluster : brute_clusters(depth)) {
    std::vector<double> mean(positions.cols(), 0.0);
    for (int64_t v : cluster) {
      for (int d = 0; d < positions.cols(); ++d) mean[d] += positions(v, d);
    }
    for (auto& m : mean) m /= static_cast<double>(cluster.size());
    int64_t best = -1;
    double best_distance = std::numeric_limits<double>::infinity();
    for (int64_t v : cluster) {
      double distance = 0.0;
      for (int d = 0; d < positions.cols(); ++d) {
        distance += (positions(v, d) - mean[d]) * (positions(v, d) - mean[d]);
      }
      if (distance < best_distance) {
        best_distance = distance;
        best = v;
      }
    }
    seeds.push_back(best);
  }
  return seeds;
}

std::vector<int64_t> brute_bi_stride_pool(const CsrGraph& graph,
                                          const std::vector<int64_t>& seeds) {
  const auto depth = all_pairs_depths(graph);
  std::vector<uint8_t> keep(graph.num_nodes, 0);
  for (int64_t seed : seeds) {
    std::vector<int64_t> even, odd;
    for (int64_t v = 0; v < graph.num_nodes; ++v) {
      if (depth[seed][v] < 0) continue;
      (depth[seed][v] % 2 == 0 ? even : odd).push_back(v);
    }
    const auto& kept = (!odd.empty() && odd.size() < even.size()) ? odd : even;
    for (int64_t v : kept) keep[v] = 1;
  }
  std::vector<int64_t> out;
  for (int64_t v = 0; v < graph.num_nodes; ++v) {
    if (keep[v]) out.push_back(v);
  }
  return out;
}

DenseBool dense_adjacency(const CsrGraph& graph) {
  DenseBool a(graph.num_nodes, std::vector<uint8_t>(graph.num_nodes, 0));
  for (int64_t i = 0; i < graph.num_nodes; ++i) {
    for (int64_t e = graph.offsets[i]; e < graph.offsets[i + 1]; ++e) a[i][graph.targets[e]] = 1;
  }
  return a;
}

DenseBool dense_from_edges(int64_t n, const EdgeList& edges) {
  DenseBool a(n, std::vector<uint8_t>(n, 0));
  for (int64_t e = 0; e < edges.size(); ++e) a[edges.sender(e)][edges.receiver(e)] = 1;
  return a;
}

DenseBool dense_product(const DenseBool& a, const DenseBool& b) {
  const size_t n = a.size();
  DenseBool c(n, std::vector<uint8_t>(n, 0));
  for (size_t i = 0; i < n; ++i) {
    for (size_t k = 0; k < n; ++k) {
      if (!a[i][k]) continue;
      for (size_t j = 0; j < n; ++j) c[i][j] |= b[k][j];
    }
  }
  return c;
}

DenseBool dense_plus_identity(DenseBool a) {
  for (size_t i = 0; i < a.size(); ++i) a[i][i] = 1;
  return a;
}

DenseBool dense_select(const DenseBool& a, const std::vector<int64_t>& rows) {
  DenseBool out(rows.size(), std::vector<uint8_t>(rows.size(), 0));
  for (size_t r = 0; r < rows.size(); ++r) {
    for (size_t c = 0; c < rows.size(); ++c) out[r][c] = a[rows[r]][rows[c]];
  }
  return out;
}

std::string csr_problem(const CsrGraph& graph) {
  const int64_t n = graph.num_nodes;
  if (static_cast<int64_t>(graph.offsets.size()) != n + 1) return "offsets size";
  if (graph.offsets[0] != 0 || graph.offsets[n] != graph.num_edges()) return "offsets ends";
  for (int64_t i = 0; i < n; ++i) {
    if (graph.offsets[i + 1] < graph.offsets[i]) return "offsets decrease";
    for (int64_t e = graph.offsets[i]; e < graph.offsets[i + 1]; ++e) {
      const int64_t j = graph.targets[e];
      if (j < 0 || j >= n) return "target out of range";
      if (j == i) return "self loop at " + std::to_string(i);
      if (e > graph.offsets[i] && graph.targets[e - 1] >= j) return "row not sorted/unique";
      if (!std::binary_search(graph.begin(j), graph.end(j), i)) return "not symmetric";
    }
  }
  return "";
}

}  // namespace bsms::test
