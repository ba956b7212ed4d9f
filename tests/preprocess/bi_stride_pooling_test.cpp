#include "preprocess/bi_stride_pooling.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "core/error.hpp"
#include "preprocess/level_transition.hpp"
#include "preprocess/multilevel_graph.hpp"
#include "test_graphs.hpp"

namespace bsms {
namespace {

ClusterNodes clusters_of(const CsrGraph& graph) {
  return group_clusters(connected_components(graph));
}

TEST(BiStridePool, EqualsBruteForceParityRule) {
  for (const auto& g : test::random_test_graphs(36, 300, 31)) {
    SCOPED_TRACE(g.name);
    const ClusterNodes clusters = clusters_of(g.graph);
    for (const auto& seeds :
         {close_center_seeds(clusters, g.positions), random_seeds(clusters, 7)}) {
      EXPECT_EQ(bi_stride_pool(g.graph, clusters, seeds),
                test::brute_bi_stride_pool(g.graph, seeds));
    }
  }
}

TEST(BiStridePool, SmallCases) {
  // Path 0-1-2-3-4 seeded at 2: even {0, 2, 4}, odd {1, 3} (fewer): keep odd.
  const CsrGraph path = graph_from_pairs(5, {0, 1, 1, 2, 2, 3, 3, 4});
  EXPECT_EQ(bi_stride_pool(path, clusters_of(path), {2}), (std::vector<int64_t>{1, 3}));
  // Path of 4 seeded at 0: even {0, 2}, odd {1, 3}: a tie keeps the even class with the seed.
  const CsrGraph four = graph_from_pairs(4, {0, 1, 1, 2, 2, 3});
  EXPECT_EQ(bi_stride_pool(four, clusters_of(four), {0}), (std::vector<int64_t>{0, 2}));
  // Star seeded at a leaf: even {leaf, other leaves}, odd {centre}: keep the centre.
  const CsrGraph star = graph_from_pairs(4, {0, 1, 0, 2, 0, 3});
  EXPECT_EQ(bi_stride_pool(star, clusters_of(star), {1}), (std::vector<int64_t>{0}));
  // Isolated nodes keep themselves.
  const CsrGraph lonely = graph_from_pairs(3, {});
  EXPECT_EQ(bi_stride_pool(lonely, clusters_of(lonely), {0, 1, 2}),
            (std::vector<int64_t>{0, 1, 2}));
}

TEST(EnhanceAdjacency, EqualsDenseFormula) {
  for (const auto& g : test::random_test_graphs(30, 200, 41)) {
    SCOPED_TRACE(g.name);
    const ClusterNodes clusters = clusters_of(g.graph);
    const auto pooled =
        bi_stride_pool(g.graph, clusters, close_center_seeds(clusters, g.positions));
    const CsrGraph coarse = enhance_adjacency(g.graph, pooled);
    ASSERT_EQ(test::csr_problem(coarse), "");
    auto a = test::dense_plus_identity(test::dense_adjacency(g.graph));
    auto expected = test::dense_select(test::dense_product(a, a), pooled);
    for (size_t i = 0; i < expected.size(); ++i) expected[i][i] = 0;
    EXPECT_EQ(test::dense_adjacency(coarse), expected);
  }
}

TEST(TransitionWeights, MatchDefinitionAndSumToOne) {
  for (const auto& g : test::random_test_graphs(24, 300, 51)) {
    SCOPED_TRACE(g.name);
    const int64_t n = g.graph.num_nodes;
    std::mt19937_64 rng(n);
    std::uniform_real_distribution<double> unit(0.5, 2.0);
    std::vector<double> w(n);
    for (auto& x : w) x = unit(rng);
    std::vector<int64_t> pooled;
    for (int64_t v = 0; v < n; v += 2) pooled.push_back(v);
    const TransitionWeights t = transition_weights(g.graph, w, pooled);
    ASSERT_EQ(static_cast<int64_t>(t.down_weight.size()), g.graph.num_edges());
    // Independent evaluation from the edge list.
    const EdgeList edges = g.graph.edges();
    std::vector<double> outdeg(n, 0.0), incoming(n, 0.0), sum(n, 0.0);
    for (int64_t e = 0; e < edges.size(); ++e) outdeg[edges.sender(e)] += 1.0;
    for (int64_t e = 0; e < edges.size(); ++e) {
      incoming[edges.receiver(e)] += w[edges.sender(e)] / outdeg[edges.sender(e)];
    }
    for (int64_t e = 0; e < edges.size(); ++e) {
      const int64_t i = edges.sender(e), j = edges.receiver(e);
      const double expected = w[i] / outdeg[i] / incoming[j];
      EXPECT_NEAR(t.down_weight[e], expected, 1e-6 * expected);
      sum[j] += t.down_weight[e];
    }
    for (int64_t j = 0; j < n; ++j) {
      if (g.graph.degree(j) > 0) {
        EXPECT_NEAR(sum[j], 1.0, 1e-5) << "receiver " << j;
      }
    }
    for (size_t r = 0; r < pooled.size(); ++r) {
      const int64_t j = pooled[r];
      EXPECT_NEAR(t.node_weight[r], g.graph.degree(j) > 0 ? incoming[j] : w[j], 1e-12);
    }
  }
}

// The properties of docs/design.md on every level of multilevel graphs of many random meshes.
TEST(MultilevelProperties, HoldOnRandomMeshesForEverySeeding) {
  int checked_levels = 0;
  for (Seeding seeding : {Seeding::kCloseCenter, Seeding::kMinAve, Seeding::kRandom}) {
    for (const auto& g : test::random_test_graphs(90, 600, 61 + static_cast<int>(seeding))) {
      SCOPED_TRACE(g.name + " seeding " + to_string(seeding));
      BuildOptions options;
      options.seeding = seeding;
      options.num_levels = 6;
      options.rng_seed = 5;
      const MultilevelGraph ml = build_multilevel_graph(g.graph, g.positions, options);
      ASSERT_EQ(ml.num_levels(), 6);
      // Cluster label of every node of the current level, carried down through `pooled`.
      std::vector<int64_t> label = connected_components(g.graph).label;
      const int64_t clusters0 = connected_components(g.graph).count;
      for (int k = 1; k < ml.num_levels(); ++k) {
        SCOPED_TRACE("level " + std::to_string(k));
        const GraphLevel& fine = ml.levels[k - 1];
        const GraphLevel& coarse = ml.levels[k];
        ASSERT_EQ(test::csr_problem(coarse.graph), "");
        ASSERT_EQ(coarse.num_nodes(), static_cast<int64_t>(coarse.pooled.size()));
        ASSERT_TRUE(std::is_sorted(coarse.pooled.begin(), coarse.pooled.end()));
        std::vector<uint8_t> is_kept(fine.num_nodes(), 0);
        for (int64_t v : coarse.pooled) is_kept[v] = 1;
        // 2-CC: every fine node is pooled or adjacent to a pooled node.
        for (int64_t v = 0; v < fine.num_nodes(); ++v) {
          bool covered = is_kept[v];
          for (const int64_t* u = fine.graph.begin(v); u != fine.graph.end(v) && !covered; ++u) {
            covered = is_kept[*u];
          }
          ASSERT_TRUE(covered) << "node " << v << " is neither pooled nor next to a pooled node";
        }
        // No coarse edge joins two clusters; each cluster stays one cluster.
        std::vector<int64_t> coarse_label(coarse.num_nodes());
        for (int64_t r = 0; r < coarse.num_nodes(); ++r) coarse_label[r] = label[coarse.pooled[r]];
        for (int64_t r = 0; r < coarse.num_nodes(); ++r) {
          for (const int64_t* s = coarse.graph.begin(r); s != coarse.graph.end(r); ++s) {
            ASSERT_EQ(coarse_label[r], coarse_label[*s]) << "edge joins two clusters";
          }
        }
        EXPECT_EQ(connected_components(coarse.graph).count, clusters0);
        label = coarse_label;
        // Weights into each receiver sum to 1; a constant field stays constant going down.
        ASSERT_EQ(static_cast<int64_t>(coarse.down_weight.size()), fine.graph.num_edges());
        std::vector<double> into(fine.num_nodes(), 0.0);
        for (int64_t i = 0; i < fine.num_nodes(); ++i) {
          for (int64_t e = fine.graph.offsets[i]; e < fine.graph.offsets[i + 1]; ++e) {
            into[fine.graph.targets[e]] += coarse.down_weight[e];
          }
        }
        for (int64_t j = 0; j < fine.num_nodes(); ++j) {
          if (fine.graph.degree(j) > 0) {
            ASSERT_NEAR(into[j], 1.0, 1e-5) << "receiver " << j;
          }
        }
        const std::vector<double> constant(fine.num_nodes() * 2, 3.5);
        const auto down = transition_down(ml, k, constant, 2);
        for (int64_t r = 0; r < coarse.num_nodes(); ++r) {
          if (fine.graph.degree(coarse.pooled[r]) > 0) {
            ASSERT_NEAR(down[2 * r], 3.5, 1e-5);
          }
        }
        // Coarse positions are the positions of the pooled nodes.
        for (int64_t r = 0; r < coarse.num_nodes(); ++r) {
          ASSERT_EQ(coarse.positions.row(r), fine.positions.row(coarse.pooled[r]));
        }
        ++checked_levels;
      }
    }
  }
  EXPECT_EQ(checked_levels, 3 * 90 * 5);
}

TEST(LevelTransfer, MatchesDenseDefinition) {
  std::mt19937_64 rng(12);
  const auto g = test::grid_triangles(7, 6, 0.1, 0.3, rng);
  BuildOptions options;
  options.num_levels = 3;
  const MultilevelGraph ml = build_multilevel_graph(g.graph, g.positions, options);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int k = 1; k < 3; ++k) {
    const GraphLevel& fine = ml.levels[k - 1];
    const GraphLevel& coarse = ml.levels[k];
    const int64_t n = fine.num_nodes(), m = coarse.num_nodes();
    // Dense contribution table C[i][j] = down_weight of edge i->j.
    std::vector<std::vector<double>> c(n, std::vector<double>(n, 0.0));
    const EdgeList edges = fine.graph.edges();
    for (int64_t e = 0; e < edges.size(); ++e) {
      c[edges.sender(e)][edges.receiver(e)] = coarse.down_weight[e];
    }
    std::vector<double> fine_values(n), coarse_values(m);
    for (auto& v : fine_values) v = unit(rng);
    for (auto& v : coarse_values) v = unit(rng);
    const auto down = transition_down(ml, k, fine_values, 1);
    for (int64_t r = 0; r < m; ++r) {
      double expected = 0.0;
      for (int64_t i = 0; i < n; ++i) expected += c[i][coarse.pooled[r]] * fine_values[i];
      EXPECT_NEAR(down[r], expected, 1e-12);
    }
    std::vector<double> unpooled(n, 0.0);
    for (int64_t r = 0; r < m; ++r) unpooled[coarse.pooled[r]] = coarse_values[r];
    const auto up = transition_up(ml, k, coarse_values, 1);
    for (int64_t i = 0; i < n; ++i) {
      double expected = 0.0;
      for (int64_t j = 0; j < n; ++j) expected += c[i][j] * unpooled[j];
      EXPECT_NEAR(up[i], expected, 1e-12);
    }
  }
  EXPECT_THROW(transition_down(ml, 0, std::vector<double>(1), 1), InputError);
  EXPECT_THROW(transition_up(ml, 1, std::vector<double>(3), 1), InputError);
}

}  // namespace
}  // namespace bsms

namespace bsms {
namespace {

// Pooling uses the graph only: on a U-shaped strip, nodes facing each other across the gap are
// one cell apart in space but far apart along the mesh, and no coarse edge may shortcut the gap.
// A level-k edge joins nodes at most 2^k mesh hops apart (each level adds at most two hops).
TEST(MultilevelProperties, CoarseEdgesNeverShortcutTheTunnelGap) {
  const auto g = test::u_tunnel(30, 2);
  const auto depth = test::all_pairs_depths(g.graph);
  for (Seeding seeding : {Seeding::kCloseCenter, Seeding::kMinAve}) {
    BuildOptions options;
    options.seeding = seeding;
    options.num_levels = 6;
    const MultilevelGraph ml = build_multilevel_graph(g.graph, g.positions, options);
    std::vector<int64_t> to_input(g.graph.num_nodes);
    for (int64_t i = 0; i < g.graph.num_nodes; ++i) to_input[i] = i;
    int64_t max_hops = 1;
    for (int k = 1; k < ml.num_levels(); ++k) {
      std::vector<int64_t> next(ml.levels[k].num_nodes());
      for (size_t r = 0; r < next.size(); ++r) next[r] = to_input[ml.levels[k].pooled[r]];
      to_input = next;
      max_hops *= 2;
      const CsrGraph& coarse = ml.levels[k].graph;
      for (int64_t r = 0; r < coarse.num_nodes; ++r) {
        for (const int64_t* s = coarse.begin(r); s != coarse.end(r); ++s) {
          ASSERT_LE(depth[to_input[r]][to_input[*s]], max_hops)
              << "level " << k << " edge shortcuts the mesh (" << to_string(seeding) << ")";
        }
      }
    }
  }
}

}  // namespace
}  // namespace bsms
