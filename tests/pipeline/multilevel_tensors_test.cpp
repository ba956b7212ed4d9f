// A bi-stride multilevel graph (preprocess/) as model tensors (models/): the tensors hold the
// builder's edges and transition weights exactly, and the per-mesh cache builds each mesh once.
#include "pipeline/graphs/multilevel_tensors.hpp"

#include <gtest/gtest.h>
#include <torch/torch.h>

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

}  // namespace
}  // namespace bsms
