#include "models/proximity_multilevel.hpp"

#include <gtest/gtest.h>
#include <torch/torch.h>

#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <utility>
#include <vector>

#include "core/error.hpp"
#include "models/graph_ops.hpp"

namespace bsms {
namespace {

using Key = std::vector<int64_t>;
using Pairs = std::set<std::pair<int64_t, int64_t>>;

std::vector<double> rows_of(const torch::Tensor& t) {
  auto c = t.to(torch::kFloat64).contiguous();
  return std::vector<double>(c.data_ptr<double>(), c.data_ptr<double>() + c.numel());
}

std::vector<int64_t> ints_of(const torch::Tensor& t) {
  auto c = t.contiguous();
  return std::vector<int64_t>(c.data_ptr<int64_t>(), c.data_ptr<int64_t>() + c.numel());
}

Pairs edge_pairs(const EdgeIndex& e) {
  Pairs out;
  auto s = ints_of(e.senders), r = ints_of(e.receivers);
  for (size_t i = 0; i < s.size(); ++i) out.insert({s[i], r[i]});
  return out;
}

torch::Tensor chain_edges(int64_t n) {
  std::vector<int64_t> e;
  for (int64_t i = 0; i + 1 < n; ++i) e.insert(e.end(), {i, i + 1, i + 1, i});
  return torch::tensor(e, torch::kInt64).reshape({-1, 2});
}

// Checks every level of `h` against a brute-force grid coarsening of `positions` [N, d].
void expect_matches_brute_force(const torch::Tensor& positions, const MultilevelTensors& h,
                                double cell) {
  const int64_t dim = positions.size(1);
  std::vector<double> pos = rows_of(positions);
  int64_t n = positions.size(0);
  for (int k = 1; k < h.num_levels(); ++k) {
    const double size = cell * std::pow(2.0, k - 1);
    std::vector<Key> key(n, Key(dim));
    std::set<Key> occupied;
    for (int64_t i = 0; i < n; ++i) {
      for (int64_t a = 0; a < dim; ++a) {
        key[i][a] = static_cast<int64_t>(std::floor(pos[i * dim + a] / size));
      }
      occupied.insert(key[i]);
    }
    const auto& t = h.transitions[k];
    ASSERT_EQ(t.coarse_nodes, static_cast<int64_t>(occupied.size())) << "level " << k;
    ASSERT_EQ(h.num_nodes(k), t.coarse_nodes);
    EXPECT_FALSE(t.up_is_down_transpose);
    EXPECT_EQ(h.node_offsets[k], (std::vector<int64_t>{0, t.coarse_nodes}));

    // Each row of D is one occupied cell: all its members, weight 1 / count; rows sum to 1.
    auto off = ints_of(t.down_offsets), col = ints_of(t.down_columns);
    auto val = rows_of(t.down_values);
    std::vector<Key> coarse_key(t.coarse_nodes);
    std::vector<double> coarse_pos(t.coarse_nodes * dim, 0.0);
    std::set<Key> seen;
    for (int64_t c = 0; c < t.coarse_nodes; ++c) {
      ASSERT_GT(off[c + 1], off[c]) << "empty cell node " << c;
      coarse_key[c] = key[col[off[c]]];
      seen.insert(coarse_key[c]);
      double sum = 0.0;
      int64_t members = 0;
      for (int64_t i = 0; i < n; ++i) members += key[i] == coarse_key[c] ? 1 : 0;
      EXPECT_EQ(off[c + 1] - off[c], members);
      for (int64_t q = off[c]; q < off[c + 1]; ++q) {
        EXPECT_EQ(key[col[q]], coarse_key[c]);
        EXPECT_NEAR(val[q], 1.0 / static_cast<double>(members), 1e-7);
        sum += val[q];
        for (int64_t a = 0; a < dim; ++a) coarse_pos[c * dim + a] += pos[col[q] * dim + a];
      }
      EXPECT_NEAR(sum, 1.0, 1e-6);
      for (int64_t a = 0; a < dim; ++a) coarse_pos[c * dim + a] /= static_cast<double>(members);
    }
    EXPECT_EQ(seen.size(), occupied.size());

    // Up: one entry per fine node, weight 1, to the node of its cell.
    auto uoff = ints_of(t.up_offsets), ucol = ints_of(t.up_columns);
    auto uval = rows_of(t.up_values);
    for (int64_t i = 0; i < n; ++i) {
      ASSERT_EQ(uoff[i + 1] - uoff[i], 1);
      EXPECT_EQ(coarse_key[ucol[uoff[i]]], key[i]);
      EXPECT_EQ(uval[uoff[i]], 1.0);
    }

    // The model's down-transferred positions are the member means.
    auto down = transition_down(
        torch::tensor(pos, torch::kFloat64).reshape({n, dim}).to(torch::kFloat32), t);
    auto down_pos = rows_of(down);
    for (size_t q = 0; q < coarse_pos.size(); ++q) EXPECT_NEAR(down_pos[q], coarse_pos[q], 1e-5);

    // Edges: exactly the pairs of distinct occupied cells at most one cell apart per axis.
    Pairs expected;
    for (int64_t a = 0; a < t.coarse_nodes; ++a) {
      for (int64_t b = 0; b < t.coarse_nodes; ++b) {
        bool near = a != b;
        for (int64_t x = 0; x < dim; ++x) {
          near = near && std::abs(coarse_key[a][x] - coarse_key[b][x]) <= 1;
        }
        if (near) expected.insert({a, b});
      }
    }
    EXPECT_EQ(edge_pairs(h.edge_sets[k][0]), expected) << "level " << k;
    EXPECT_EQ(h.edge_sets[k][0].num_edges(), static_cast<int64_t>(expected.size()));

    pos = coarse_pos;
    n = t.coarse_nodes;
  }
}

TEST(ProximityMultilevel, HandMadeLineMatchesCellsByHand) {
  // Cells of 0.5: {-0.1} | {0, 0.1, 0.25} | {0.9} | {1.05}; then cells of 1: {-0.1}, {0.117, 0.9},
  // {1.05}.
  auto x = torch::tensor({0.0, 0.1, 0.25, 0.9, 1.05, -0.1}, torch::kFloat32).reshape({6, 1});
  auto h = make_proximity_multilevel(x, chain_edges(6), 3, 0.5);
  ASSERT_EQ(h.num_levels(), 3);
  EXPECT_EQ(h.num_nodes(0), 6);
  EXPECT_EQ(h.num_nodes(1), 4);
  EXPECT_EQ(h.num_nodes(2), 3);
  EXPECT_EQ(edge_pairs(h.edge_sets[0][0]), edge_pairs(EdgeIndex::from_pairs(chain_edges(6), 6)));
  EXPECT_EQ(edge_pairs(h.edge_sets[1][0]), (Pairs{{0, 1}, {1, 0}, {1, 2}, {2, 1}, {2, 3}, {3, 2}}));
  EXPECT_EQ(edge_pairs(h.edge_sets[2][0]), (Pairs{{0, 1}, {1, 0}, {1, 2}, {2, 1}}));
  auto p1 = rows_of(transition_down(x, h.transitions[1]));
  EXPECT_NEAR(p1[0], -0.1, 1e-6);
  EXPECT_NEAR(p1[1], 0.35 / 3.0, 1e-6);
  EXPECT_NEAR(p1[2], 0.9, 1e-6);
  EXPECT_NEAR(p1[3], 1.05, 1e-6);
  expect_matches_brute_force(x, h, 0.5);
}

TEST(ProximityMultilevel, RandomPointSetsMatchBruteForce) {
  torch::manual_seed(3);
  for (int64_t dim = 1; dim <= 3; ++dim) {
    for (int trial = 0; trial < 4; ++trial) {
      const int64_t n = 10 + 15 * trial;
      auto x = (torch::rand({n, dim}) * 4.0 - 1.5).to(torch::kFloat32);
      auto edges = torch::randint(0, n, {2 * n, 2}, torch::kInt64);
      const double cell = 0.3 + 0.2 * trial;
      auto h = make_proximity_multilevel(x, edges, 4, cell);
      ASSERT_EQ(h.num_levels(), 4);
      EXPECT_EQ(h.edge_sets[0][0].num_edges(), 2 * n);  // level 0: the mesh edges as given
      SCOPED_TRACE("dim " + std::to_string(dim) + ", trial " + std::to_string(trial));
      expect_matches_brute_force(x, h, cell);
    }
  }
}

TEST(ProximityMultilevel, TransfersAndGradientsMatchDenseMatrices) {
  torch::manual_seed(4);
  auto x = torch::rand({30, 2}) * 3.0;
  auto h = make_proximity_multilevel(x, torch::zeros({0, 2}, torch::kInt64), 3, 0.4);
  for (size_t k = 1; k < h.transitions.size(); ++k) {
    const auto& t = h.transitions[k];
    // Dense D [coarse, fine] and U [fine, coarse] from the CSR arrays.
    auto d = torch::zeros({t.coarse_nodes, t.fine_nodes});
    auto u = torch::zeros({t.fine_nodes, t.coarse_nodes});
    auto off = ints_of(t.down_offsets), col = ints_of(t.down_columns);
    auto val = rows_of(t.down_values);
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

TEST(ProximityMultilevel, MergesAsABatch) {
  auto x1 = torch::tensor({0.0, 0.3, 0.6, 0.9}, torch::kFloat32).reshape({4, 1});
  auto x2 = torch::tensor({5.0, 5.2}, torch::kFloat32).reshape({2, 1});
  auto h1 = make_proximity_multilevel(x1, chain_edges(4), 3, 0.5);
  auto h2 = make_proximity_multilevel(x2, chain_edges(2), 3, 0.5);
  auto merged = merge_multilevel_tensors({&h1, &h2});
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

TEST(ProximityMultilevel, RejectsBadInput) {
  auto x = torch::rand({5, 2});
  auto e = chain_edges(5);
  EXPECT_THROW(make_proximity_multilevel(torch::rand({5}), e, 2, 0.5), InputError);
  EXPECT_THROW(make_proximity_multilevel(torch::rand({0, 2}), e, 2, 0.5), InputError);
  EXPECT_THROW(make_proximity_multilevel(torch::rand({5, 4}), e, 2, 0.5), InputError);
  EXPECT_THROW(make_proximity_multilevel(torch::ones({5, 2}, torch::kInt64), e, 2, 0.5),
               InputError);
  auto bad = x.clone();
  bad[2][1] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(make_proximity_multilevel(bad, e, 2, 0.5), InputError);
  EXPECT_THROW(make_proximity_multilevel(x, e, 0, 0.5), InputError);
  EXPECT_THROW(make_proximity_multilevel(x, e, 2, 0.0), InputError);
  EXPECT_THROW(make_proximity_multilevel(x, e, 2, -1.0), InputError);
  EXPECT_THROW(make_proximity_multilevel(x, e, 2, std::numeric_limits<double>::infinity()),
               InputError);
  EXPECT_THROW(make_proximity_multilevel(x, e.to(torch::kFloat32), 2, 0.5), InputError);
  EXPECT_THROW(
      make_proximity_multilevel(x, torch::tensor({0, 5}, torch::kInt64).reshape({1, 2}), 2, 0.5),
      InputError);
  EXPECT_THROW(make_proximity_multilevel(x, torch::zeros({3, 3}, torch::kInt64), 2, 0.5),
               InputError);
  try {
    make_proximity_multilevel(x, e, 2, 0.0);
  } catch (const InputError& err) {
    EXPECT_NE(std::string(err.what()).find("cell_size"), std::string::npos) << err.what();
  }
}

}  // namespace
}  // namespace bsms
