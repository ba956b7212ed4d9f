// Proximity coarsening (thesis §4.4): each level against a brute-force grid binning on random
// point sets and meshes, plus cases worked out by hand.
#include "preprocess/proximity_pooling.hpp"

#include <gtest/gtest-spi.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "core/error.hpp"
#include "test_graphs.hpp"

namespace bsms {
namespace {

using Key = std::vector<int64_t>;
using Pairs = std::set<std::pair<int64_t, int64_t>>;

Pairs pair_set(const EdgeList& edges) {
  Pairs out;
  for (int64_t e = 0; e < edges.size(); ++e) out.insert({edges.sender(e), edges.receiver(e)});
  return out;
}

EdgeList chain_edges(int64_t n) {
  EdgeList edges;
  for (int64_t i = 0; i + 1 < n; ++i) edges.data.insert(edges.data.end(), {i, i + 1, i + 1, i});
  return edges;
}

RowMatrixXd column(const std::vector<double>& x) {
  RowMatrixXd out(static_cast<int64_t>(x.size()), 1);
  for (size_t i = 0; i < x.size(); ++i) out(static_cast<int64_t>(i), 0) = x[i];
  return out;
}

// Checks level k (>= 1) of `graph` against a brute-force binning of level k-1's positions.
void expect_level_matches_brute_force(const ProximityMultilevelGraph& graph, int k,
                                      double cell_size) {
  SCOPED_TRACE("level " + std::to_string(k));
  const RowMatrixXd& fine = graph.levels[k - 1].positions;
  const ProximityLevel& level = graph.levels[k];
  const int64_t n = fine.rows(), dim = fine.cols();
  const double size = cell_size * std::pow(2.0, k - 1);
  std::vector<Key> key(n, Key(dim));
  std::set<Key> occupied;
  for (int64_t i = 0; i < n; ++i) {
    for (int64_t a = 0; a < dim; ++a)
      key[i][a] = static_cast<int64_t>(std::floor(fine(i, a) / size));
    occupied.insert(key[i]);
  }
  ASSERT_EQ(level.num_nodes, static_cast<int64_t>(occupied.size()));
  ASSERT_EQ(level.cluster_of.size(), static_cast<size_t>(n));
  ASSERT_EQ(level.member_offsets.size(), static_cast<size_t>(level.num_nodes + 1));
  ASSERT_EQ(level.members.size(), static_cast<size_t>(n));
  ASSERT_EQ(level.member_weight.size(), static_cast<size_t>(n));
  ASSERT_EQ(level.positions.rows(), level.num_nodes);
  ASSERT_EQ(level.positions.cols(), dim);

  // Coarse nodes are the occupied cells in lexicographic order of their coordinates; each lists
  // exactly the fine nodes in it, ascending, with weight 1 / count, and sits at their mean.
  std::vector<Key> coarse_key(occupied.begin(), occupied.end());
  std::vector<int> seen(n, 0);
  for (int64_t c = 0; c < level.num_nodes; ++c) {
    std::vector<int64_t> expected;
    for (int64_t i = 0; i < n; ++i) {
      if (key[i] == coarse_key[c]) expected.push_back(i);
    }
    const std::vector<int64_t> members(level.members.begin() + level.member_offsets[c],
                                       level.members.begin() + level.member_offsets[c + 1]);
    EXPECT_EQ(members, expected) << "cell node " << c;
    double weight_sum = 0.0;
    for (int64_t q = level.member_offsets[c]; q < level.member_offsets[c + 1]; ++q) {
      EXPECT_EQ(level.member_weight[q], 1.0f / static_cast<float>(expected.size()));
      weight_sum += level.member_weight[q];
      EXPECT_EQ(level.cluster_of[level.members[q]], c);
      ++seen[level.members[q]];
    }
    EXPECT_NEAR(weight_sum, 1.0, 1e-6);
    for (int64_t a = 0; a < dim; ++a) {
      double mean = 0.0;
      for (int64_t i : expected) mean += fine(i, a) / static_cast<double>(expected.size());
      EXPECT_NEAR(level.positions(c, a), mean, 1e-12 * (1.0 + std::abs(mean)));
    }
  }
  for (int64_t i = 0; i < n; ++i) EXPECT_EQ(seen[i], 1) << "fine node " << i;

  // Edges: exactly the pairs of distinct occupied cells at most one cell apart per axis, each
  // once, grouped by sender in node order.
  Pairs expected;
  for (int64_t a = 0; a < level.num_nodes; ++a) {
    for (int64_t b = 0; b < level.num_nodes; ++b) {
      bool near = a != b;
      for (int64_t x = 0; x < dim; ++x) {
        near = near && std::abs(coarse_key[a][x] - coarse_key[b][x]) <= 1;
      }
      if (near) expected.insert({a, b});
    }
  }
  EXPECT_EQ(pair_set(level.edges), expected);
  EXPECT_EQ(level.edges.size(), static_cast<int64_t>(expected.size()));
  for (int64_t e = 1; e < level.edges.size(); ++e) {
    EXPECT_LE(level.edges.sender(e - 1), level.edges.sender(e));
  }
}

void expect_matches_brute_force(const ProximityMultilevelGraph& graph, double cell_size) {
  for (int k = 1; k < graph.num_levels(); ++k) {
    expect_level_matches_brute_force(graph, k, cell_size);
  }
}

TEST(ProximityPooling, HandMadeLineMatchesCellsByHand) {
  // Cells of 0.5: {-0.1} | {0, 0.1, 0.25} | {0.9} | {1.05}; then cells of 1: {-0.1}, {0.117, 0.9},
  // {1.05}.
  const RowMatrixXd x = column({0.0, 0.1, 0.25, 0.9, 1.05, -0.1});
  const auto graph = build_proximity_multilevel_graph(x, chain_edges(6), 3, 0.5);
  ASSERT_EQ(graph.num_levels(), 3);
  EXPECT_EQ(graph.levels[0].num_nodes, 6);
  EXPECT_EQ(graph.levels[1].num_nodes, 4);
  EXPECT_EQ(graph.levels[2].num_nodes, 3);
  EXPECT_EQ(graph.levels[0].edges.data, chain_edges(6).data);
  EXPECT_EQ(graph.levels[1].edges.data, (std::vector<int64_t>{0, 1, 1, 0, 1, 2, 2, 1, 2, 3, 3, 2}));
  EXPECT_EQ(graph.levels[2].edges.data, (std::vector<int64_t>{0, 1, 1, 0, 1, 2, 2, 1}));
  EXPECT_EQ(graph.levels[1].cluster_of, (std::vector<int64_t>{1, 1, 1, 2, 3, 0}));
  EXPECT_EQ(graph.levels[1].member_offsets, (std::vector<int64_t>{0, 1, 4, 5, 6}));
  EXPECT_EQ(graph.levels[1].members, (std::vector<int64_t>{5, 0, 1, 2, 3, 4}));
  EXPECT_EQ(graph.levels[1].member_weight[1], 1.0f / 3.0f);
  EXPECT_EQ(graph.levels[2].cluster_of, (std::vector<int64_t>{0, 1, 1, 2}));
  EXPECT_NEAR(graph.levels[1].positions(0, 0), -0.1, 1e-15);
  EXPECT_NEAR(graph.levels[1].positions(1, 0), 0.35 / 3.0, 1e-15);
  EXPECT_NEAR(graph.levels[1].positions(2, 0), 0.9, 1e-15);
  EXPECT_NEAR(graph.levels[1].positions(3, 0), 1.05, 1e-15);
  expect_matches_brute_force(graph, 0.5);
}

TEST(ProximityPooling, BruteForceCheckSeesSmallErrors) {
  // The oracle still has the power to fail: one wrong weight bit, position or edge order.
  const RowMatrixXd x = column({0.0, 0.1, 0.25, 0.9, 1.05, -0.1});
  const auto graph = build_proximity_multilevel_graph(x, chain_edges(6), 2, 0.5);
  auto weight = graph;
  weight.levels[1].member_weight[1] = std::nextafter(1.0f / 3.0f, 1.0f);
  EXPECT_NONFATAL_FAILURE(expect_level_matches_brute_force(weight, 1, 0.5), "member_weight");
  auto position = graph;
  position.levels[1].positions(1, 0) += 1e-9;
  EXPECT_NONFATAL_FAILURE(expect_level_matches_brute_force(position, 1, 0.5), "positions");
  auto order = graph;
  std::swap(order.levels[1].edges.data[0], order.levels[1].edges.data[2]);  // (1, 0) before (0, 1)
  std::swap(order.levels[1].edges.data[1], order.levels[1].edges.data[3]);
  EXPECT_NONFATAL_FAILURE(expect_level_matches_brute_force(order, 1, 0.5), "sender");
}

TEST(ProximityPooling, ChainOfSticksHalvesPerLevel) {
  // 2^5 + 1 nodes dx apart, level-1 cells of 2 dx (the heat-sticks setting): each level pairs up
  // the nodes of the one below except the last, 2^(5-k) + 1 nodes on a chain.
  const int64_t n = 33;
  const double dx = 1.0 / static_cast<double>(n - 1);
  std::vector<double> x;
  for (int64_t i = 0; i < n; ++i) x.push_back(dx * static_cast<double>(i));
  const auto graph = build_proximity_multilevel_graph(column(x), chain_edges(n), 6, 2.0 * dx);
  ASSERT_EQ(graph.num_levels(), 6);
  for (int k = 0; k < 6; ++k) {
    const int64_t nodes = (int64_t{1} << (5 - k)) + 1;
    EXPECT_EQ(graph.levels[k].num_nodes, nodes) << "level " << k;
    EXPECT_EQ(graph.levels[k].edges.data, chain_edges(nodes).data) << "level " << k;
  }
  expect_matches_brute_force(graph, 2.0 * dx);
}

TEST(ProximityPooling, PoolsNodesAcrossAGap) {
  // Two sticks with a gap of a quarter node spacing: the first level already puts the end of one
  // and the start of the other in one cell, which bi-stride pooling never does.
  const int64_t n = 9;
  const double dx = 1.0 / static_cast<double>(n - 1);
  std::vector<double> x;
  for (int64_t i = 0; i < n; ++i) x.push_back(dx * static_cast<double>(i));
  for (int64_t i = 0; i < n; ++i) x.push_back(1.0 + 0.25 * dx + dx * static_cast<double>(i));
  EdgeList edges = chain_edges(n);
  for (int64_t i = 0; i + 1 < n; ++i) edges.data.insert(edges.data.end(), {n + i, n + i + 1});
  const auto graph = build_proximity_multilevel_graph(column(x), edges, 2, 2.0 * dx);
  const ProximityLevel& level = graph.levels[1];
  EXPECT_EQ(level.cluster_of[n - 1], level.cluster_of[n]);
  EXPECT_EQ(graph.levels[0].edges.data, edges.data);  // level 0 as given, duplicates and order
  expect_matches_brute_force(graph, 2.0 * dx);
}

TEST(ProximityPooling, RandomPointSetsMatchBruteForce) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> coordinate(-1.5, 2.5);
  for (int64_t dim = 1; dim <= 3; ++dim) {
    for (int trial = 0; trial < 4; ++trial) {
      const int64_t n = 10 + 15 * trial;
      RowMatrixXd x(n, dim);
      for (int64_t i = 0; i < n; ++i) {
        for (int64_t a = 0; a < dim; ++a) x(i, a) = coordinate(rng);
      }
      std::uniform_int_distribution<int64_t> node(0, n - 1);
      EdgeList edges;
      for (int64_t e = 0; e < 4 * n; ++e) edges.data.push_back(node(rng));
      const double cell = 0.3 + 0.2 * trial;
      SCOPED_TRACE("dim " + std::to_string(dim) + ", trial " + std::to_string(trial));
      const auto graph = build_proximity_multilevel_graph(x, edges, 4, cell);
      ASSERT_EQ(graph.num_levels(), 4);
      EXPECT_EQ(graph.levels[0].edges.data, edges.data);
      expect_matches_brute_force(graph, cell);
    }
  }
}

TEST(ProximityPooling, RandomMeshesMatchBruteForceAndAreDeterministic) {
  for (const auto& g : test::random_test_graphs(12, 300, 41)) {
    SCOPED_TRACE(g.name);
    const auto graph = build_proximity_multilevel_graph(g.positions, g.graph.edges(), 4, 0.7);
    expect_matches_brute_force(graph, 0.7);
    for (int k = 1; k < graph.num_levels(); ++k) {
      // Coarse edges are symmetric and free of self loops.
      const Pairs pairs = pair_set(graph.levels[k].edges);
      for (const auto& [s, r] : pairs) {
        EXPECT_NE(s, r);
        EXPECT_TRUE(pairs.count({r, s})) << s << " -> " << r;
      }
    }
    const auto again = build_proximity_multilevel_graph(g.positions, g.graph.edges(), 4, 0.7);
    for (int k = 0; k < graph.num_levels(); ++k) {
      EXPECT_EQ(again.levels[k].edges.data, graph.levels[k].edges.data);
      EXPECT_EQ(again.levels[k].cluster_of, graph.levels[k].cluster_of);
      EXPECT_EQ(again.levels[k].member_weight, graph.levels[k].member_weight);
      EXPECT_TRUE(again.levels[k].positions == graph.levels[k].positions);
    }
  }
}

TEST(ProximityPooling, OneLevelIsTheInputGraph) {
  const RowMatrixXd x = column({0.0, 0.3, 0.6});
  const auto graph = build_proximity_multilevel_graph(x, chain_edges(3), 1, 0.5);
  ASSERT_EQ(graph.num_levels(), 1);
  EXPECT_EQ(graph.levels[0].num_nodes, 3);
  EXPECT_EQ(graph.levels[0].edges.data, chain_edges(3).data);
  EXPECT_TRUE(graph.levels[0].positions == x);
}

TEST(ProximityPooling, RejectsBadInput) {
  const RowMatrixXd x = RowMatrixXd::Random(5, 2);
  const EdgeList e = chain_edges(5);
  EXPECT_THROW(build_proximity_multilevel_graph(RowMatrixXd(5, 0), e, 2, 0.5), InputError);
  EXPECT_THROW(build_proximity_multilevel_graph(RowMatrixXd(0, 2), EdgeList{}, 2, 0.5), InputError);
  EXPECT_THROW(build_proximity_multilevel_graph(RowMatrixXd::Zero(5, 4), e, 2, 0.5), InputError);
  RowMatrixXd bad = x;
  bad(2, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(build_proximity_multilevel_graph(bad, e, 2, 0.5), InputError);
  bad(2, 1) = 1e16;
  EXPECT_THROW(build_proximity_multilevel_graph(bad, e, 2, 1.0), InputError);
  EXPECT_THROW(build_proximity_multilevel_graph(x, e, 0, 0.5), InputError);
  EXPECT_THROW(build_proximity_multilevel_graph(x, e, 2, 0.0), InputError);
  EXPECT_THROW(build_proximity_multilevel_graph(x, e, 2, -1.0), InputError);
  EXPECT_THROW(build_proximity_multilevel_graph(x, e, 2, std::numeric_limits<double>::infinity()),
               InputError);
  EXPECT_THROW(build_proximity_multilevel_graph(x, EdgeList{{0, 5}}, 2, 0.5), InputError);
  EXPECT_THROW(build_proximity_multilevel_graph(x, EdgeList{{-1, 0}}, 2, 0.5), InputError);
  try {
    build_proximity_multilevel_graph(x, e, 2, 0.0);
    ADD_FAILURE() << "no error";
  } catch (const InputError& err) {
    EXPECT_NE(std::string(err.what()).find("cell_size"), std::string::npos) << err.what();
  }
}

}  // namespace
}  // namespace bsms
