#include "preprocess/seeding.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include "core/error.hpp"
#include "test_graphs.hpp"

namespace bsms {
namespace {

ClusterNodes clusters_of(const CsrGraph& graph) {
  return group_clusters(connected_components(graph));
}

TEST(GroupClusters, NodesAscendingPerComponent) {
  std::mt19937_64 rng(3);
  const auto g = test::several_clusters(4, 3, rng);
  const Components components = connected_components(g.graph);
  const ClusterNodes clusters = group_clusters(components);
  ASSERT_EQ(clusters.count, components.count);
  int64_t total = 0;
  for (int64_t c = 0; c < clusters.count; ++c) {
    for (const int64_t* v = clusters.begin(c); v != clusters.end(c); ++v) {
      EXPECT_EQ(components.label[*v], c);
      if (v != clusters.begin(c)) {
        EXPECT_LT(*(v - 1), *v);
      }
    }
    total += clusters.size(c);
  }
  EXPECT_EQ(total, g.graph.num_nodes);
}

TEST(CloseCenter, EqualsBruteForceOnRandomMeshes) {
  for (const auto& g : test::random_test_graphs(36, 300, 11)) {
    SCOPED_TRACE(g.name);
    EXPECT_EQ(close_center_seeds(clusters_of(g.graph), g.positions),
              test::brute_close_center_seeds(g.graph, g.positions));
  }
}

TEST(CloseCenter, TiesGoToTheLowestIndex) {
  // Unjittered square grid: the centre of a 2x2 cell grid is a node; of a 1x1 grid all four
  // corners tie and node 0 wins.
  std::mt19937_64 rng(1);
  const auto one = test::grid_triangles(1, 1, 0.0, 0.0, rng);
  EXPECT_EQ(close_center_seeds(clusters_of(one.graph), one.positions), std::vector<int64_t>{0});
  const auto two = test::grid_triangles(2, 2, 0.0, 0.0, rng);
  EXPECT_EQ(close_center_seeds(clusters_of(two.graph), two.positions), std::vector<int64_t>{4});
}

TEST(MinAve, EqualsBruteForceOnRandomMeshes) {
  for (const auto& g : test::random_test_graphs(48, 400, 21)) {
    SCOPED_TRACE(g.name);
    EXPECT_EQ(min_ave_seeds(g.graph, clusters_of(g.graph)), test::brute_min_ave_seeds(g.graph));
  }
}

TEST(MinAve, EqualsBruteForceOnLargerMeshesWithPruning) {
  // Clusters above 256 nodes take the pruned path (blobs, lower bounds, cut-off BFS).
  std::mt19937_64 rng(5);
  std::vector<test::TestGraph> graphs;
  graphs.push_back(test::grid_triangles(40, 30, 0.0, 0.3, rng));
  graphs.push_back(test::grid_triangles(45, 45, 0.08, 0.3, rng));
  graphs.push_back(test::grid_triangles(60, 8, 0.0, 0.0, rng));  // exact ties by symmetry
  graphs.push_back(test::grid_tets(8, 9, 10, 0.1, rng));
  graphs.push_back(test::u_tunnel(60, 3));
  graphs.push_back(test::random_graph(900, 1, rng));
  for (auto& g : test::random_test_graphs(30, 1500, 22)) graphs.push_back(std::move(g));
  for (const auto& g : graphs) {
    SCOPED_TRACE(g.name);
    MinAveStats stats;
    EXPECT_EQ(min_ave_seeds(g.graph, clusters_of(g.graph), &stats),
              test::brute_min_ave_seeds(g.graph));
  }
}

TEST(MinAve, LowerBoundsNeverExceedTheTrueSums) {
  for (const auto& g : test::random_test_graphs(24, 1200, 23)) {
    SCOPED_TRACE(g.name);
    const auto depth = test::all_pairs_depths(g.graph);
    const ClusterNodes clusters = clusters_of(g.graph);
    for (int64_t c = 0; c < clusters.count; ++c) {
      const std::vector<int64_t> nodes(clusters.begin(c), clusters.end(c));
      const auto bound = distance_sum_lower_bounds(g.graph, nodes);
      ASSERT_EQ(bound.size(), nodes.size());
      for (size_t i = 0; i < nodes.size(); ++i) {
        int64_t sum = 0;
        for (int64_t u : nodes) sum += depth[nodes[i]][u];
        ASSERT_LE(bound[i], sum) << "node " << nodes[i];
        ASSERT_GE(bound[i], 0);
      }
    }
  }
}

TEST(MinAve, PrunesMostCandidatesOnAMesh) {
  std::mt19937_64 rng(8);
  const auto g = test::grid_triangles(70, 70, 0.0, 0.3, rng);
  MinAveStats stats;
  const auto seeds = min_ave_seeds(g.graph, clusters_of(g.graph), &stats);
  EXPECT_EQ(seeds, test::brute_min_ave_seeds(g.graph));
  EXPECT_GT(stats.bound_bfs, 0);
  EXPECT_LT(stats.evaluated, g.graph.num_nodes / 4) << "pruning rejected too few candidates";
  EXPECT_EQ(stats.evaluated + stats.pruned, g.graph.num_nodes);
}

TEST(MinAve, SameResultWithOneAndTwoThreads) {
  std::mt19937_64 rng(9);
  const auto g = test::several_clusters(3, 2, rng);
  const auto big = test::grid_triangles(50, 40, 0.05, 0.3, rng);
  const int before = omp_get_max_threads();  // restored: later tests keep their thread count
  for (const auto* graph : {&g.graph, &big.graph}) {
    const ClusterNodes clusters = clusters_of(*graph);
    omp_set_num_threads(1);
    const auto one = min_ave_seeds(*graph, clusters);
    omp_set_num_threads(2);
    const auto two = min_ave_seeds(*graph, clusters);
    EXPECT_EQ(one, two);
  }
  omp_set_num_threads(before);
}

TEST(DistanceSums, MatchBruteForce) {
  std::mt19937_64 rng(4);
  const auto g = test::grid_tets(4, 5, 3, 0.0, rng);
  const auto depth = test::all_pairs_depths(g.graph);
  std::vector<int64_t> sources;
  for (int64_t v = 0; v < 64 && 2 * v < g.graph.num_nodes; ++v) sources.push_back(2 * v);
  const auto sums = distance_sums(g.graph, sources, g.graph.num_nodes);
  for (size_t b = 0; b < sources.size(); ++b) {
    int64_t expected = 0;
    for (int64_t d : depth[sources[b]]) expected += d;
    EXPECT_EQ(sums[b], expected) << "source " << sources[b];
  }
  EXPECT_THROW(distance_sums(g.graph, std::vector<int64_t>(65, 0), 1), InputError);
}

TEST(RandomSeeding, DeterministicPerSeedAndInsideEachCluster) {
  std::mt19937_64 rng(6);
  const auto g = test::several_clusters(5, 4, rng);
  const ClusterNodes clusters = clusters_of(g.graph);
  const Components components = connected_components(g.graph);
  const auto a = random_seeds(clusters, 42);
  EXPECT_EQ(a, random_seeds(clusters, 42));
  bool differs = false;
  for (uint64_t seed = 1; seed < 8; ++seed) differs |= random_seeds(clusters, seed) != a;
  EXPECT_TRUE(differs) << "the seed has no effect";
  for (int64_t c = 0; c < clusters.count; ++c) EXPECT_EQ(components.label[a[c]], c);
}

}  // namespace
}  // namespace bsms
