// Multilevel graphs of preprocess/ (bi-stride, proximity) as model tensors (models/): the tensors
// hold the builder's edges and transition weights exactly, and the per-mesh cache builds each mesh
// once.
#include "pipeline/graphs/multilevel_tensors.hpp"

#include <gtest/gtest.h>
#include <torch/torch.h>

#include <random>
#include <vector>

#include "core/error.hpp"
#include "core/graph.hpp"
#include "models/graph_ops.hpp"

namespace bsms {
namespace {

// Triangulated nx × ny grid (unit spacing) and its bi-stride multilevel graph with exact A².
MultilevelGraph grid_multilevel(int64_t nx, int64_t ny, int levels) {
  auto id = [&](int64_t x, int64_t y) { return y * nx + x; };
  std::vector<int64_t> pairs;
  RowMatrixXd positions(nx * ny, 2);
  for (int64_t y = 0; y < ny; ++y) {
    for (int64_t x = 0; x < nx; ++x) {
      positions(id(x, y), 0) = static_cast<double>(x);
      positions(id(x, y), 1) = static_cast<double>(y);
      if (x + 1 < nx) pairs.insert(pairs.end(), {id(x, y), id(x + 1, y)});
      if (y + 1 < ny) pairs.insert(pairs.end(), {id(x, y), id(x, y + 1)});
      if (x + 1 < nx && y + 1 < ny) pairs.insert(pairs.end(), {id(x, y), id(x + 1, y + 1)});
    }
  }
  BuildOptions options;
  options.num_levels = levels;
  return build_multilevel_graph(graph_from_pairs(nx * ny, pairs), positions, options);
}

// [E, 2] int64 (sender, receiver) of a CSR graph, in CSR order.
torch::Tensor edge_pairs(const CsrGraph& g) {
  std::vector<int64_t> data = g.edges().data;
  return torch::tensor(data, torch::kInt64).reshape({g.num_edges(), 2});
}

TEST(MultilevelTensors, HoldTheGraphsAndTransitionWeights) {
  const MultilevelGraph graph = grid_multilevel(7, 5, 4);
  ASSERT_EQ(graph.num_levels(), 4);
  const MultilevelTensors h = make_multilevel_tensors(graph);
  ASSERT_EQ(h.num_levels(), 4);
  ASSERT_EQ(h.transitions.size(), 4u);  // transitions[0] is empty: index = coarse level
  EXPECT_EQ(h.num_graphs(), 1);
  for (int k = 0; k < 4; ++k) {
    const GraphLevel& level = graph.levels[k];
    EXPECT_EQ(h.num_nodes(k), level.num_nodes());
    EXPECT_EQ(h.node_offsets[k], (std::vector<int64_t>{0, level.num_nodes()}));
    const EdgeIndex& e = h.edge_sets[k][0];
    EXPECT_TRUE(torch::equal(torch::stack({e.senders, e.receivers}, 1), edge_pairs(level.graph)));
    if (k == 0) continue;
    // Down matrix against the file's definition: D[c, i] = down_weight of the fine edge
    // i -> pooled[c] (docs/design.md "Bi-stride multilevel building" item 6), read off the weights
    // in CSR edge order.
    const CsrGraph& fine = graph.levels[k - 1].graph;
    auto dense = torch::zeros({fine.num_nodes, fine.num_nodes});
    for (int64_t i = 0; i < fine.num_nodes; ++i) {
      for (int64_t p = fine.offsets[i]; p < fine.offsets[i + 1]; ++p) {
        dense[fine.targets[p]][i] = level.down_weight[p];
      }
    }
    auto expected = dense.index_select(0, torch::tensor(level.pooled, torch::kInt64));
    const LevelTransition& t = h.transitions[k];
    EXPECT_EQ(t.fine_nodes, fine.num_nodes);
    EXPECT_EQ(t.coarse_nodes, level.num_nodes());
    EXPECT_TRUE(t.up_is_down_transpose);
    auto down = transition_down(torch::eye(fine.num_nodes), t);
    EXPECT_LT((down - expected).abs().max().item<double>(), 1e-6);
    auto up = transition_up(torch::eye(level.num_nodes()), t);
    EXPECT_LT((up - expected.t()).abs().max().item<double>(), 1e-6);
  }
  const MultilevelTensors top2 = make_multilevel_tensors(graph, 2);
  EXPECT_EQ(top2.num_levels(), 2);
  EXPECT_EQ(top2.transitions.size(), 2u);
}

TEST(MultilevelTensors, RefuseGraphsThatDoNotFit) {
  EXPECT_THROW(make_multilevel_tensors(MultilevelGraph{}), InputError);
  MultilevelGraph short_weights = grid_multilevel(5, 4, 3);
  short_weights.levels[2].down_weight.pop_back();
  EXPECT_THROW(make_multilevel_tensors(short_weights), InputError);
  EXPECT_EQ(make_multilevel_tensors(short_weights, 2).num_levels(), 2);  // level 2 is not read
  MultilevelGraph bad_pooled = grid_multilevel(5, 4, 3);
  bad_pooled.levels[1].pooled.back() = bad_pooled.levels[0].num_nodes();
  EXPECT_THROW(make_multilevel_tensors(bad_pooled), InputError);
}

TEST(MultilevelTensorCache, BuildsEachMeshOnceAndKeepsTheLastBatch) {
  const MultilevelGraph graph = grid_multilevel(4, 4, 3);
  MultilevelTensorCache cache;
  const auto& h = cache.get("grid", graph);
  EXPECT_EQ(&h, &cache.get("grid", graph));  // built once
  EXPECT_EQ(h.num_levels(), 3);
  EXPECT_TRUE(cache.contains("grid"));
  EXPECT_FALSE(cache.contains("other"));
  const auto& b = cache.batch({"grid", "grid"});
  EXPECT_EQ(b.num_nodes(0), 32);
  EXPECT_EQ(&b, &cache.batch({"grid", "grid"}));
  EXPECT_THROW(cache.batch({"other"}), InputError);
  MultilevelTensorCache two_levels(2);
  EXPECT_EQ(two_levels.get("grid", graph).num_levels(), 2);
}

// A proximity multilevel graph of `n` random points in [0, 3)^dim, random level-0 edges.
ProximityMultilevelGraph random_proximity(int64_t n, int64_t dim, int levels, double cell,
                                          uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> coordinate(0.0, 3.0);
  std::uniform_int_distribution<int64_t> node(0, n - 1);
  RowMatrixXd x(n, dim);
  for (int64_t i = 0; i < n; ++i) {
    for (int64_t a = 0; a < dim; ++a) x(i, a) = coordinate(rng);
  }
  EdgeList edges;
  for (int64_t e = 0; e < 4 * n; ++e) edges.data.push_back(node(rng));
  return build_proximity_multilevel_graph(x, edges, levels, cell);
}

std::vector<int64_t> ints_of(const torch::Tensor& t) {
  auto c = t.contiguous();
  return std::vector<int64_t>(c.data_ptr<int64_t>(), c.data_ptr<int64_t>() + c.numel());
}

std::vector<float> floats_of(const torch::Tensor& t) {
  auto c = t.contiguous();
  return std::vector<float>(c.data_ptr<float>(), c.data_ptr<float>() + c.numel());
}

// Positions [N, d] as a float32 tensor.
torch::Tensor position_tensor(const RowMatrixXd& x) {
  return torch::from_blob(const_cast<double*>(x.data()), {x.rows(), x.cols()}, torch::kFloat64)
      .to(torch::kFloat32);
}

TEST(MultilevelTensors, HoldTheProximityGraphAndCellTransitions) {
  for (int64_t dim = 1; dim <= 3; ++dim) {
    SCOPED_TRACE("dim " + std::to_string(dim));
    const ProximityMultilevelGraph graph = random_proximity(40, dim, 4, 0.4, 5 + dim);
    const MultilevelTensors h = make_multilevel_tensors(graph);
    ASSERT_EQ(h.num_levels(), 4);
    ASSERT_EQ(h.transitions.size(), 4u);
    EXPECT_EQ(h.num_graphs(), 1);
    for (int k = 0; k < 4; ++k) {
      const ProximityLevel& level = graph.levels[k];
      EXPECT_EQ(h.num_nodes(k), level.num_nodes);
      EXPECT_EQ(h.node_offsets[k], (std::vector<int64_t>{0, level.num_nodes}));
      const EdgeIndex& e = h.edge_sets[k][0];
      EXPECT_EQ(ints_of(torch::stack({e.senders, e.receivers}, 1)), level.edges.data);
      if (k == 0) continue;
      const LevelTransition& t = h.transitions[k];
      EXPECT_EQ(t.fine_nodes, graph.levels[k - 1].num_nodes);
      EXPECT_EQ(t.coarse_nodes, level.num_nodes);
      EXPECT_FALSE(t.up_is_down_transpose);
      EXPECT_EQ(ints_of(t.down_offsets), level.member_offsets);
      EXPECT_EQ(ints_of(t.down_columns), level.members);
      EXPECT_EQ(floats_of(t.down_values), level.member_weight);
      std::vector<int64_t> one_each(t.fine_nodes + 1);
      for (int64_t i = 0; i <= t.fine_nodes; ++i) one_each[i] = i;
      EXPECT_EQ(ints_of(t.up_offsets), one_each);
      EXPECT_EQ(ints_of(t.up_columns), level.cluster_of);
      EXPECT_EQ(floats_of(t.up_values), std::vector<float>(t.fine_nodes, 1.0f));
      // The model's down-transferred positions are the cells' member means.
      auto down = transition_down(position_tensor(graph.levels[k - 1].positions), t);
      EXPECT_LT((down - position_tensor(level.positions)).abs().max().item<double>(), 1e-5);
    }
  }
  EXPECT_THROW(make_multilevel_tensors(ProximityMultilevelGraph{}), InputError);
}

TEST(MultilevelTensors, ProximityTransfersAndGradientsMatchDenseMatrices) {
  torch::manual_seed(4);
  const MultilevelTensors h = make_multilevel_tensors(random_proximity(30, 2, 3, 0.4, 4));
  for (size_t k = 1; k < h.transitions.size(); ++k) {
    const auto& t = h.transitions[k];
    // Dense D [coarse, fine] and U [fine, coarse] from the CSR arrays.
    auto d = torch::zeros({t.coarse_nodes, t.fine_nodes});
    auto u = torch::zeros({t.fine_nodes, t.coarse_nodes});
    auto off = ints_of(t.down_offsets), col = ints_of(t.down_columns);
    auto val = floats_of(t.down_values);
    for (int64_t c = 0; c < t.coarse_nodes; ++c) {
      for (int64_t q = off[c]; q < off[c + 1]; ++q) d[c][col[q]] = val[q];
    }
    auto uoff = ints_of(t.up_offsets), ucol = ints_of(t.up_columns);
    for (int64_t i = 0; i < t.fine_nodes; ++i) u[i][ucol[uoff[i]]] = 1.0;
    auto v = torch::randn({t.fine_nodes, 5}, torch::requires_grad());
    auto w = torch::randn({t.coarse_nodes, 5}, torch::requires_grad());
    auto down = transition_down(v, t);
    auto up = transition_up(w, t);
    EXPECT_TRUE(torch::allclose(down, d.mm(v), 1e-5, 1e-6));
    EXPECT_TRUE(torch::allclose(up, u.mm(w), 1e-5, 1e-6));
    auto gd = torch::randn_like(down), gu = torch::randn_like(up);
    ((down * gd).sum() + (up * gu).sum()).backward();
    EXPECT_TRUE(torch::allclose(v.grad(), d.t().mm(gd), 1e-5, 1e-6));
    EXPECT_TRUE(torch::allclose(w.grad(), u.t().mm(gu), 1e-5, 1e-6));
  }
}

TEST(MultilevelTensors, ProximityGraphsMergeAsABatch) {
  EdgeList chain4{{0, 1, 1, 0, 1, 2, 2, 1, 2, 3, 3, 2}}, chain2{{0, 1, 1, 0}};
  RowMatrixXd x1(4, 1), x2(2, 1);
  x1 << 0.0, 0.3, 0.6, 0.9;
  x2 << 5.0, 5.2;
  const auto h1 = make_multilevel_tensors(build_proximity_multilevel_graph(x1, chain4, 3, 0.5));
  const auto h2 = make_multilevel_tensors(build_proximity_multilevel_graph(x2, chain2, 3, 0.5));
  const auto merged = merge_multilevel_tensors({&h1, &h2});
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(merged.node_offsets[k],
              (std::vector<int64_t>{0, h1.num_nodes(k), h1.num_nodes(k) + h2.num_nodes(k)}));
  }
  for (int k = 0; k < 2; ++k) {
    EXPECT_FALSE(merged.transitions[k + 1].up_is_down_transpose);
    auto v = torch::randn({merged.num_nodes(k), 3});
    auto expected =
        torch::cat({transition_down(v.slice(0, 0, h1.num_nodes(k)), h1.transitions[k + 1]),
                    transition_down(v.slice(0, h1.num_nodes(k)), h2.transitions[k + 1])});
    EXPECT_TRUE(torch::allclose(transition_down(v, merged.transitions[k + 1]), expected));
  }
}

}  // namespace
}  // namespace bsms
