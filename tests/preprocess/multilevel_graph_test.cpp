#include "preprocess/multilevel_graph.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include "core/error.hpp"
#include "preprocess/edge_thinning.hpp"
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
      // Thinned hierarchies (CloseCenter) and exact ones (the others).
      if (seeding == Seeding::kCloseCenter) options.thinning = Thinning::kOn;
      options.rng_seed = 17;
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
    for (Thinning thinning : {Thinning::kAuto, Thinning::kOff}) {
      SCOPED_TRACE(g.name + " thinning " + to_string(thinning));
      BuildOptions options;  // auto levels
      options.thinning = thinning;
      const MultilevelGraph ml = build_multilevel_graph(g.graph, g.positions, options);
      ASSERT_GE(ml.num_levels(), 1);
      EXPECT_EQ(ml.thinned, thinning == Thinning::kAuto);
      int64_t coarse_edges = 0;
      for (int k = 1; k < ml.num_levels(); ++k) {
        EXPECT_TRUE(auto_accepts_level(ml.levels[k].graph, ml.levels[k - 1].num_nodes(),
                                       g.graph.num_edges(), coarse_edges, ml.thinned));
        coarse_edges += ml.levels[k].graph.num_edges();
      }
      if (ml.thinned) {
        EXPECT_LE(coarse_edges, kAutoMaxEdgesFactor * g.graph.num_edges());
      }
      // The next level would have been rejected (or the level cap was reached).
      if (ml.num_levels() < kAutoMaxLevels) {
        const GraphLevel next = coarsen_level(ml.levels.back(), options.seeding, 0, ml.thinned);
        EXPECT_FALSE(auto_accepts_level(next.graph, ml.levels.back().num_nodes(),
                                        g.graph.num_edges(), coarse_edges, ml.thinned));
      }
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
  const CsrGraph path = graph_from_pairs(40, pairs);  // 78 directed edges
  for (bool thinned : {false, true}) {
    EXPECT_TRUE(auto_accepts_level(path, 80, 1000, 0, thinned));
    EXPECT_FALSE(auto_accepts_level(path, 40, 1000, 0, thinned));  // no fewer nodes
    EXPECT_TRUE(auto_accepts_level(path, 80, 39, 0, thinned));     // twice the edges of level 0
    EXPECT_FALSE(auto_accepts_level(path, 80, 38, 0, thinned));    // more than twice
  }
  // Exact A²: each level alone is bounded; thinned: all coarse levels together.
  EXPECT_TRUE(auto_accepts_level(path, 80, 100, 150, false));
  EXPECT_FALSE(auto_accepts_level(path, 80, 100, 150, true));  // 150 + 78 > 2 x 100
  EXPECT_TRUE(auto_accepts_level(path, 80, 100, 122, true));   // 122 + 78 = 200
  // Complete graph on 20 nodes: dense.
  std::vector<int64_t> all;
  for (int64_t i = 0; i < 20; ++i) {
    for (int64_t j = i + 1; j < 20; ++j) all.insert(all.end(), {i, j});
  }
  EXPECT_FALSE(auto_accepts_level(graph_from_pairs(20, all), 80, 100000, 0, true));
  // Tiny: 10 nodes.
  EXPECT_FALSE(auto_accepts_level(graph_from_pairs(10, {0, 1}), 80, 1000, 0, true));
}

TEST(BuildMultilevel, ThinningNamesAndDefaults) {
  for (Thinning t : {Thinning::kAuto, Thinning::kOn, Thinning::kOff}) {
    EXPECT_EQ(parse_thinning(to_string(t)), t);
  }
  EXPECT_THROW(parse_thinning("yes"), InputError);
  std::mt19937_64 rng(5);
  const auto g = test::grid_triangles(60, 50, 0.0, 0.3, rng);
  // A requested level count keeps the exact A² unless thinning is asked for.
  BuildOptions exact;
  exact.num_levels = 6;
  BuildOptions off = exact;
  off.thinning = Thinning::kOff;
  const MultilevelGraph a = build_multilevel_graph(g.graph, g.positions, exact);
  const MultilevelGraph b = build_multilevel_graph(g.graph, g.positions, off);
  EXPECT_FALSE(a.thinned);
  expect_identical(a, b);
  BuildOptions on = exact;
  on.thinning = Thinning::kOn;
  const MultilevelGraph c = build_multilevel_graph(g.graph, g.positions, on);
  EXPECT_TRUE(c.thinned);
  ASSERT_EQ(c.num_levels(), 6);                       // still the count asked for
  EXPECT_EQ(c.levels[1].pooled, a.levels[1].pooled);  // level 1 pools level 0, unchanged
  int64_t exact_edges = 0, thinned_edges = 0;
  for (int k = 1; k < 6; ++k) {
    exact_edges += a.levels[k].graph.num_edges();
    thinned_edges += c.levels[k].graph.num_edges();
  }
  EXPECT_LT(thinned_edges, exact_edges);
  // Thinning needs positions.
  EXPECT_THROW(build_multilevel_graph(g.graph, RowMatrixXd(), on), InputError);
  BuildOptions automatic;  // auto levels without positions: exact A², per-level bound
  automatic.seeding = Seeding::kMinAve;
  EXPECT_FALSE(build_multilevel_graph(g.graph, RowMatrixXd(), automatic).thinned);
}

// The point of thinning: on a 2D mesh the exact hierarchy's degree doubles per level and its
// coarse levels cost several times the mesh; thinned, the degree stays bounded, the coarse levels
// together stay within kAutoMaxEdgesFactor x level 0, and the hierarchy still gets deep (a small
// coarsest level).
TEST(BuildMultilevel, ThinnedAutoHierarchyIsSparseAndDeep) {
  std::mt19937_64 rng(9);
  const auto g = test::grid_triangles(200, 150, 0.0, 0.3, rng);  // 30K nodes
  const MultilevelGraph thin = build_multilevel_graph(g.graph, g.positions, BuildOptions{});
  ASSERT_TRUE(thin.thinned);
  BuildOptions exact_options;
  exact_options.num_levels = thin.num_levels();
  const MultilevelGraph exact = build_multilevel_graph(g.graph, g.positions, exact_options);
  int64_t thin_edges = 0, exact_edges = 0;
  double max_thin_degree = 0.0, max_exact_degree = 0.0;
  for (int k = 1; k < thin.num_levels(); ++k) {
    thin_edges += thin.levels[k].graph.num_edges();
    exact_edges += exact.levels[k].graph.num_edges();
    max_thin_degree = std::max(max_thin_degree, mean_degree(thin.levels[k].graph));
    max_exact_degree = std::max(max_exact_degree, mean_degree(exact.levels[k].graph));
  }
  EXPECT_GE(thin.num_levels(), 8);
  EXPECT_LE(thin.levels.back().num_nodes(), 1000);
  EXPECT_LE(thin_edges, kAutoMaxEdgesFactor * g.graph.num_edges());
  EXPECT_LE(max_thin_degree, 4.0 * thinning_cones(2));
  EXPECT_GT(max_exact_degree, 4.0 * max_thin_degree);  // measured 136 against 18
  EXPECT_GT(exact_edges, 3 * thin_edges / 2);          // measured 578K against 359K
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
