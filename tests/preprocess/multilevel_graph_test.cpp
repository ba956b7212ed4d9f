#include "preprocess/multilevel_graph.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include "core/error.hpp"
#include "test_graphs.hpp"

namespace bsms {
namespace {

void expect_identical(const MultilevelGraph& a, const MultilevelGraph& b) {
  ASSERT_EQ(a.num_levels(), b.num_levels());
  for (int k = 0; k < a.num_levels(); ++k) {
    EXPECT_EQ(a.levels[k].graph.offsets, b.levels[k].graph.offsets) << "level " << k;
    EXPECT_EQ(a.levels[k].graph.targets, b.levels[k].graph.targets) << "level " << k;
    EXPECT_EQ(a.levels[k].pooled, b.levels[k].pooled) << "level " << k;
    EXPECT_EQ(a.levels[k].down_weight, b.levels[k].down_weight) << "level " << k;  // bitwise
  }
}

TEST(SeedingNames, RoundTripAndReject) {
  for (Seeding s : {Seeding::kCloseCenter, Seeding::kMinAve, Seeding::kRandom}) {
    EXPECT_EQ(parse_seeding(to_string(s)), s);
  }
  EXPECT_THROW(parse_seeding("MinAve"), InputError);
}

TEST(BuildMultilevel, DeterministicAcrossRunsAndThreadCounts) {
  const int saved = omp_get_max_threads();
  for (Seeding seeding : {Seeding::kCloseCenter, Seeding::kMinAve, Seeding::kRandom}) {
    for (const auto& g : test::random_test_graphs(6, 3000, 91)) {
      SCOPED_TRACE(g.name + " " + to_string(seeding));
      BuildOptions options;
      options.seeding = seeding;
      options.num_levels = 5;
      options.seed = 17;
      omp_set_num_threads(1);
      const MultilevelGraph one = build_multilevel_graph(g.graph, g.positions, options);
      omp_set_num_threads(2);
      const MultilevelGraph two = build_multilevel_graph(g.graph, g.positions, options);
      const MultilevelGraph again = build_multilevel_graph(g.graph, g.positions, options);
      expect_identical(one, two);
      expect_identical(two, again);
    }
  }
  omp_set_num_threads(saved);
}

TEST(BuildMultilevel, RequestedLevelCountIsExact) {
  std::mt19937_64 rng(2);
  const auto g = test::grid_triangles(6, 6, 0.0, 0.2, rng);
  for (int levels : {1, 2, 5, 12}) {
    BuildOptions options;
    options.num_levels = levels;
    const MultilevelGraph ml = build_multilevel_graph(g.graph, g.positions, options);
    EXPECT_EQ(ml.num_levels(), levels);
    EXPECT_EQ(ml.levels[0].graph.targets, g.graph.targets);
    EXPECT_TRUE(ml.levels[0].pooled.empty());
  }
  BuildOptions bad;
  bad.num_levels = -1;
  EXPECT_THROW(build_multilevel_graph(g.graph, g.positions, bad), InputError);
}

TEST(BuildMultilevel, AutoStopsBeforeDenseOrTinyLevels) {
  std::mt19937_64 rng(3);
  for (const auto& g : {test::grid_triangles(120, 100, 0.0, 0.3, rng),
                        test::grid_tets(14, 14, 14, 0.0, rng), test::several_clusters(3, 5, rng)}) {
    SCOPED_TRACE(g.name);
    BuildOptions options;  // auto
    const MultilevelGraph ml = build_multilevel_graph(g.graph, g.positions, options);
    ASSERT_GE(ml.num_levels(), 1);
    for (int k = 1; k < ml.num_levels(); ++k) {
      EXPECT_TRUE(auto_accepts_level(ml.levels[k].graph, ml.levels[k - 1].num_nodes(),
                                     g.graph.num_edges()));
    }
    // The next level would have been rejected (or the level cap was reached).
    if (ml.num_levels() < kAutoMaxLevels) {
      const GraphLevel next = coarsen_level(ml.levels.back(), options.seeding, 0);
      EXPECT_FALSE(
          auto_accepts_level(next.graph, ml.levels.back().num_nodes(), g.graph.num_edges()));
    }
  }
  // A mesh big enough gets several levels.
  const auto big = test::grid_triangles(120, 100, 0.0, 0.3, rng);
  EXPECT_GE(build_multilevel_graph(big.graph, big.positions, BuildOptions{}).num_levels(), 5);
}

TEST(BuildMultilevel, AutoRuleDecisions) {
  // A path of 40 nodes as a candidate: sparse, one cluster of 40.
  std::vector<int64_t> pairs;
  for (int64_t i = 0; i + 1 < 40; ++i) pairs.insert(pairs.end(), {i, i + 1});
  const CsrGraph path = graph_from_pairs(40, pairs);
  EXPECT_TRUE(auto_accepts_level(path, 80, 1000));
  EXPECT_FALSE(auto_accepts_level(path, 40, 1000));  // no fewer nodes
  EXPECT_TRUE(auto_accepts_level(path, 80, 39));     // twice the edges of level 0
  EXPECT_FALSE(auto_accepts_level(path, 80, 38));    // more than twice
  // Complete graph on 20 nodes: dense.
  std::vector<int64_t> all;
  for (int64_t i = 0; i < 20; ++i) {
    for (int64_t j = i + 1; j < 20; ++j) all.insert(all.end(), {i, j});
  }
  EXPECT_FALSE(auto_accepts_level(graph_from_pairs(20, all), 80, 100000));
  // Tiny: 10 nodes.
  EXPECT_FALSE(auto_accepts_level(graph_from_pairs(10, {0, 1}), 80, 1000));
}

TEST(BuildMultilevel, FromMeshUsesTheMeshGraph) {
  RowMatrixXd points(4, 2);
  points << 0, 0, 1, 0, 1, 1, 0, 1;
  RowMatrixXi64 cells(2, 3);
  cells << 0, 1, 2, 0, 2, 3;
  const Mesh mesh = make_mesh(2, points, cells);
  BuildOptions options;
  options.num_levels = 2;
  std::vector<LevelReport> report;
  const MultilevelGraph ml = build_multilevel_graph(mesh, options, &report);
  EXPECT_EQ(ml.levels[0].graph.num_edges(), 10);  // 5 undirected edges
  ASSERT_EQ(report.size(), 2u);
  EXPECT_EQ(report[0].nodes, 4);
  EXPECT_EQ(report[0].edges, 10);
  EXPECT_DOUBLE_EQ(report[0].mean_degree, 2.5);
  EXPECT_EQ(report[1].nodes, ml.levels[1].num_nodes());
  EXPECT_EQ(report[1].clusters, 1);
}

}  // namespace
}  // namespace bsms
