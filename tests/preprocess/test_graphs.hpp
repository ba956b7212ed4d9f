// Random test meshes and brute-force references for the preprocessor tests.
#pragma once

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "core/graph.hpp"
#include "core/mesh.hpp"

namespace bsms::test {

struct TestGraph {
  std::string name;
  CsrGraph graph;
  RowMatrixXd positions;  // [N, dim]
};

// Structured (nx x ny) grid of quads, each split into two triangles along a random diagonal;
// every cell is removed with probability `hole_fraction` (holes, several clusters, isolated
// nodes: nodes stay numbered even when no cell uses them); positions jittered by `jitter` cells.
TestGraph grid_triangles(int nx, int ny, double hole_fraction, double jitter, std::mt19937_64& rng);

// (nx x ny x nz) grid of cubes split into 6 tetrahedra each, cells removed like grid_triangles.
TestGraph grid_tets(int nx, int ny, int nz, double hole_fraction, std::mt19937_64& rng);

// A U-shaped strip of triangles: two arms `length` cells long and `width` cells wide joined at the
// bottom, separated by a one-cell gap, so nodes facing each other across the gap are spatially
// close and geodesically far.
TestGraph u_tunnel(int length, int width);

// Several random meshes side by side plus `isolated` nodes without edges, node order shuffled.
TestGraph several_clusters(int clusters, int isolated, std::mt19937_64& rng);

// A sparse random graph (not a mesh): n nodes, each joined to `degree` random others.
TestGraph random_graph(int n, int degree, std::mt19937_64& rng);

// The mix used by property tests: `count` graphs of the kinds above with random parameters,
// at most about `max_nodes` nodes each.
std::vector<TestGraph> random_test_graphs(int count, int max_nodes, uint64_t seed);

// Brute-force references (O(N^2) or dense; small graphs only).
std::vector<std::vector<int64_t>> all_pairs_depths(const CsrGraph& graph);
std::vector<int64_t> brute_min_ave_seeds(const CsrGraph& graph);  // per component label
std::vector<int64_t> brute_close_center_seeds(const CsrGraph& graph, const RowMatrixXd& positions);
std::vector<int64_t> brute_bi_stride_pool(const CsrGraph& graph, const std::vector<int64_t>& seeds);

using DenseBool = std::vector<std::vector<uint8_t>>;
DenseBool dense_adjacency(const CsrGraph& graph);
DenseBool dense_from_edges(int64_t n, const EdgeList& edges);
DenseBool dense_product(const DenseBool& a, const DenseBool& b);
DenseBool dense_plus_identity(DenseBool a);
DenseBool dense_select(const DenseBool& a, const std::vector<int64_t>& rows);

// Checks CSR invariants: offsets, sorted unique rows, in range, no self loops, symmetric.
// Returns an empty string when all hold, else what failed.
std::string csr_problem(const CsrGraph& graph);

}  // namespace bsms::test
