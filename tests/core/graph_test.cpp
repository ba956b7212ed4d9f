#include "core/graph.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>

namespace bsms {
namespace {

std::vector<int64_t> random_pairs(std::mt19937& rng, int64_t n, int64_t m) {
  std::uniform_int_distribution<int64_t> pick(0, n - 1);
  std::vector<int64_t> pairs;
  for (int64_t e = 0; e < m; ++e) {
    pairs.push_back(pick(rng));
    pairs.push_back(pick(rng));
  }
  return pairs;
}

TEST(Graph, FromPairsIsSymmetricSortedWithoutLoopsOrDuplicates) {
  std::mt19937 rng(1);
  for (int trial = 0; trial < 50; ++trial) {
    const int64_t n = 1 + trial * 7;
    const auto pairs = random_pairs(rng, n, 3 * n);
    const CsrGraph g = graph_from_pairs(n, pairs);
    std::set<std::pair<int64_t, int64_t>> expected;
    for (size_t p = 0; p < pairs.size(); p += 2) {
      if (pairs[p] == pairs[p + 1]) continue;
      expected.insert({pairs[p], pairs[p + 1]});
      expected.insert({pairs[p + 1], pairs[p]});
    }
    const EdgeList edges = g.edges();
    ASSERT_EQ(edges.size(), static_cast<int64_t>(expected.size()));
    int64_t e = 0;
    for (const auto& [a, b] : expected) {  // std::set order = sorted by sender, then receiver
      EXPECT_EQ(edges.sender(e), a);
      EXPECT_EQ(edges.receiver(e), b);
      ++e;
    }
  }
}

TEST(Graph, MeshGraphJoinsNodesSharingACell) {
  RowMatrixXd points(4, 2);
  points << 0, 0, 1, 0, 1, 1, 0, 1;
  RowMatrixXi64 cells(2, 3);
  cells << 0, 1, 2, 0, 2, 3;
  const CsrGraph g = mesh_graph(make_mesh(2, points, cells));
  EXPECT_EQ(g.num_edges(), 10);  // 5 undirected edges
  EXPECT_EQ(g.degree(0), 3);
  EXPECT_EQ(g.degree(1), 2);
  EXPECT_EQ(std::vector<int64_t>(g.begin(3), g.end(3)), (std::vector<int64_t>{0, 2}));
}

// Brute-force references: union-find components and Bellman-Ford-style relaxation depths.
int64_t find_root(std::vector<int64_t>& parent, int64_t x) {
  while (parent[x] != x) x = parent[x] = parent[parent[x]];
  return x;
}

TEST(Graph, ComponentsAndBfsMatchBruteForceOnRandomGraphs) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 40; ++trial) {
    const int64_t n = 2 + trial * 5;
    const auto pairs = random_pairs(rng, n, n / 2 + trial % 5);
    const CsrGraph g = graph_from_pairs(n, pairs);
    std::vector<int64_t> parent(n);
    for (int64_t i = 0; i < n; ++i) parent[i] = i;
    for (size_t p = 0; p < pairs.size(); p += 2)
      parent[find_root(parent, pairs[p])] = find_root(parent, pairs[p + 1]);
    const Components comp = connected_components(g);
    std::set<int64_t> roots;
    for (int64_t i = 0; i < n; ++i) roots.insert(find_root(parent, i));
    ASSERT_EQ(comp.count, static_cast<int64_t>(roots.size()));
    for (int64_t i = 0; i < n; ++i)
      for (int64_t j = i + 1; j < n; ++j)
        ASSERT_EQ(comp.label[i] == comp.label[j], find_root(parent, i) == find_root(parent, j));
    // Components are numbered by their lowest node.
    int64_t next = 0;
    for (int64_t i = 0; i < n; ++i)
      if (comp.label[i] == next)
        ++next;
      else
        ASSERT_LT(comp.label[i], next);

    const int64_t source = static_cast<int64_t>(rng() % n);
    const auto depth = bfs_depths(g, source);
    std::vector<int64_t> ref(n, kUnreached);
    ref[source] = 0;
    for (bool changed = true; changed;) {
      changed = false;
      for (size_t p = 0; p < pairs.size(); p += 2) {
        for (int dir = 0; dir < 2; ++dir) {
          const int64_t a = pairs[p + dir], b = pairs[p + 1 - dir];
          if (ref[a] != kUnreached && (ref[b] == kUnreached || ref[b] > ref[a] + 1)) {
            ref[b] = ref[a] + 1;
            changed = true;
          }
        }
      }
    }
    ASSERT_EQ(depth, ref);
  }
}

}  // namespace
}  // namespace bsms
