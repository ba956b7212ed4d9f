#include "preprocess/edge_thinning.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include <array>
#include <cmath>
#include <limits>

#include "core/error.hpp"
#include "preprocess/bi_stride_pooling.hpp"
#include "preprocess/multilevel_graph.hpp"
#include "test_graphs.hpp"

namespace bsms {
namespace {

bool has_edge(const CsrGraph& g, int64_t i, int64_t j) {
  return std::binary_search(g.begin(i), g.end(i), j);
}

// The cone of direction d among the documented directions, written out independently.
int brute_cone(int dim, const std::array<double, 3>& d) {
  std::vector<std::array<double, 3>> dirs;
  if (dim == 1) {
    dirs = {{1, 0, 0}, {-1, 0, 0}};
  } else if (dim == 2) {
    for (int s = 0; s < 8; ++s) dirs.push_back({std::cos(s * M_PI / 4), std::sin(s * M_PI / 4), 0});
  } else {
    dirs = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    const double c = 1 / std::sqrt(3.0);
    for (double x : {c, -c})
      for (double y : {c, -c})
        for (double z : {c, -c}) dirs.push_back({x, y, z});
  }
  int best = 0;
  double best_dot = -std::numeric_limits<double>::infinity();
  for (size_t s = 0; s < dirs.size(); ++s) {
    const double dot = d[0] * dirs[s][0] + d[1] * dirs[s][1] + d[2] * dirs[s][2];
    if (dot > best_dot) {
      best_dot = dot;
      best = static_cast<int>(s);
    }
  }
  return best;
}

// The coarse A² graphs of random meshes: dense enough for thinning to act.
std::vector<test::TestGraph> coarse_graphs(int count, int max_nodes, uint64_t seed) {
  std::vector<test::TestGraph> out;
  for (auto& g : test::random_test_graphs(count, max_nodes, seed)) {
    GraphLevel level;
    level.graph = g.graph;
    level.positions = g.positions;
    for (int k = 0; k < 2 && level.num_nodes() > 1; ++k) {
      level = coarsen_level(level, Seeding::kCloseCenter, 0);
    }
    out.push_back({g.name, level.graph, level.positions});
  }
  return out;
}

TEST(EdgeThinning, ConeCounts) {
  EXPECT_EQ(thinning_cones(1), 2);
  EXPECT_EQ(thinning_cones(2), 8);
  EXPECT_EQ(thinning_cones(3), 14);
  EXPECT_THROW(thinning_cones(4), InputError);
}

// Against a brute-force statement of the rule: an edge survives iff an end of degree > 2C
// chose it as its nearest or farthest neighbour in that neighbour's cone, or an end has degree
// <= 2C; nothing else except edges put back to keep clusters whole.
TEST(EdgeThinning, EqualsBruteForceRuleAndKeepsClusters) {
  int64_t thinned_somewhere = 0;
  for (const auto& g : coarse_graphs(40, 1500, 123)) {
    SCOPED_TRACE(g.name);
    const int dim = static_cast<int>(g.positions.cols());
    const int64_t limit = 2 * thinning_cones(dim);
    ThinningReport report;
    const CsrGraph t = thin_adjacency(g.graph, g.positions, &report);
    ASSERT_EQ(test::csr_problem(t), "");
    thinned_somewhere += report.thinned_nodes;
    auto chooses = [&](int64_t i, int64_t j) {
      if (g.graph.degree(i) <= limit) return true;
      std::array<double, 3> dj{0, 0, 0};
      for (int c = 0; c < dim; ++c) dj[c] = g.positions(j, c) - g.positions(i, c);
      const int cone = brute_cone(dim, dj);
      const double lj = dj[0] * dj[0] + dj[1] * dj[1] + dj[2] * dj[2];
      bool nearest = true, farthest = true;
      for (const int64_t* k = g.graph.begin(i); k != g.graph.end(i); ++k) {
        if (*k == j) continue;
        std::array<double, 3> dk{0, 0, 0};
        for (int c = 0; c < dim; ++c) dk[c] = g.positions(*k, c) - g.positions(i, c);
        if (brute_cone(dim, dk) != cone) continue;
        const double lk = dk[0] * dk[0] + dk[1] * dk[1] + dk[2] * dk[2];
        if (lk < lj || (lk == lj && *k < j)) nearest = false;
        if (lk > lj || (lk == lj && *k < j)) farthest = false;
      }
      return nearest || farthest;
    };
    int64_t extra = 0;
    for (int64_t i = 0; i < g.graph.num_nodes; ++i) {
      for (const int64_t* j = g.graph.begin(i); j != g.graph.end(i); ++j) {
        const bool rule = chooses(i, *j) || chooses(*j, i);
        const bool kept = has_edge(t, i, *j);
        if (rule) {
          EXPECT_TRUE(kept) << i << " -> " << *j;
        }
        if (kept && !rule) ++extra;
      }
      for (const int64_t* j = t.begin(i); j != t.end(i); ++j) {
        EXPECT_TRUE(has_edge(g.graph, i, *j)) << "new edge " << i << " -> " << *j;
      }
    }
    EXPECT_EQ(extra, report.restored_edges);
    // Same clusters.
    EXPECT_EQ(connected_components(t).label, connected_components(g.graph).label);
  }
  EXPECT_GT(thinned_somewhere, 100);  // the cases exercise thinning
}

TEST(EdgeThinning, RestoresConnectivityWithShortestEdges) {
  // A star whose centre has 20 leaves in one direction: the centre keeps its nearest and
  // farthest leaf; each leaf (degree 1) keeps its own edge, so nothing is lost.
  std::vector<int64_t> pairs;
  RowMatrixXd pos(21, 2);
  pos.row(0) << 0, 0;
  for (int i = 1; i <= 20; ++i) {
    pos.row(i) << i, 0.001 * i;
    pairs.insert(pairs.end(), {0, i});
  }
  const CsrGraph star = graph_from_pairs(21, pairs);
  EXPECT_EQ(thin_adjacency(star, pos).targets, star.targets);
  // Two hubs a and b, each with 19 leaves along the line towards the other at distances 1..20
  // (not 10), joined by one bridge of length 10: in each hub's cone the bridge is neither the
  // nearest nor the farthest neighbour, so the rule drops it and the cluster would split; it is
  // put back.
  std::vector<int64_t> p2;
  RowMatrixXd q(40, 2);
  q.row(0) << 0, 0;   // a
  q.row(1) << 10, 0;  // b
  int64_t next = 2;
  for (int d = 1; d <= 20; ++d) {
    if (d == 10) continue;
    q.row(next) << d, 0.01;
    p2.insert(p2.end(), {0, next++});
    q.row(next) << 10 - d, -0.01;
    p2.insert(p2.end(), {1, next++});
  }
  p2.insert(p2.end(), {0, 1});
  const CsrGraph two = graph_from_pairs(40, p2);
  ThinningReport report;
  const CsrGraph t = thin_adjacency(two, q, &report);
  EXPECT_EQ(report.thinned_nodes, 2);
  EXPECT_EQ(report.restored_edges, 2);
  EXPECT_TRUE(has_edge(t, 0, 1));
  EXPECT_EQ(t.num_edges(), two.num_edges());  // every leaf edge is kept by its leaf
}

TEST(EdgeThinning, IndependentOfThreadCount) {
  const int saved = omp_get_max_threads();
  std::mt19937_64 rng(4);
  auto g = test::grid_triangles(260, 200, 0.02, 0.3, rng);  // > 16K coarse nodes: parallel
  GraphLevel level;
  level.graph = g.graph;
  level.positions = g.positions;
  level = coarsen_level(level, Seeding::kCloseCenter, 0);
  level = coarsen_level(level, Seeding::kCloseCenter, 0);
  omp_set_num_threads(1);
  const CsrGraph one = thin_adjacency(level.graph, level.positions);
  omp_set_num_threads(2);
  const CsrGraph two = thin_adjacency(level.graph, level.positions);
  omp_set_num_threads(saved);
  EXPECT_EQ(one.offsets, two.offsets);
  EXPECT_EQ(one.targets, two.targets);
}

TEST(EdgeThinning, RejectsMissingPositions) {
  const CsrGraph g = graph_from_pairs(3, {0, 1, 1, 2});
  EXPECT_THROW(thin_adjacency(g, RowMatrixXd(2, 2)), InputError);
  EXPECT_THROW(thin_adjacency(g, RowMatrixXd(3, 4)), InputError);
}

}  // namespace
}  // namespace bsms
