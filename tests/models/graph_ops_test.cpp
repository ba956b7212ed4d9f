#include "models/graph_ops.hpp"

#include <gtest/gtest.h>
#include <torch/torch.h>

#include "core/error.hpp"
#include "models/graph_tensors.hpp"
#include "tests/models/graph_fixtures.hpp"

namespace bsms {
namespace {

// Random directed edges with duplicates and self loops, unsorted: [E, 2].
torch::Tensor random_pairs(int64_t num_nodes, int64_t num_edges) {
  return torch::randint(0, num_nodes, {num_edges, 2}, torch::kInt64);
}

void expect_close(const torch::Tensor& a, const torch::Tensor& b, double tol = 1e-5) {
  ASSERT_EQ(a.sizes(), b.sizes());
  EXPECT_LT((a - b).abs().max().item<double>(), tol * (1.0 + b.abs().max().item<double>()));
}

TEST(EdgeIndex, GroupsEdgesBySenderAndReceiver) {
  torch::manual_seed(1);
  auto pairs = random_pairs(7, 40);
  auto index = EdgeIndex::from_pairs(pairs, 7);
  for (int side = 0; side < 2; ++side) {
    auto key = side == 0 ? index.senders : index.receivers;
    auto off = side == 0 ? index.sender_offsets : index.receiver_offsets;
    auto order = side == 0 ? index.sender_order : index.receiver_order;
    EXPECT_TRUE(torch::equal(key, pairs.select(1, side)));
    ASSERT_EQ(off.size(0), 8);
    EXPECT_EQ(off[7].item<int64_t>(), 40);
    for (int64_t n = 0; n < 7; ++n) {
      auto group = order.slice(0, off[n].item<int64_t>(), off[n + 1].item<int64_t>());
      EXPECT_TRUE(key.index_select(0, group).eq(n).all().item<bool>());
      EXPECT_EQ(group.size(0), key.eq(n).sum().item<int64_t>());
      EXPECT_TRUE(group.equal(std::get<0>(group.sort())));  // stable: ascending edge ids
    }
  }
}

TEST(EdgeIndex, RejectsOutOfRangeAndBadShape) {
  auto bad = torch::tensor({0, 1, 1, 5}, torch::kInt64).reshape({2, 2});
  EXPECT_THROW(EdgeIndex::from_pairs(bad, 5), InputError);
  EXPECT_THROW(EdgeIndex::from_pairs(torch::zeros({3, 3}, torch::kInt64), 5), InputError);
}

// Runs f and g on the same leaves with the same upstream weights; compares outputs and gradients.
template <class F, class G>
void expect_same_function(std::vector<torch::Tensor> leaves, const F& f, const G& g) {
  std::vector<std::vector<torch::Tensor>> grads(2);
  std::vector<torch::Tensor> outs;
  torch::Tensor weight;
  for (int pass = 0; pass < 2; ++pass) {
    for (auto& t : leaves) {
      if (t.grad().defined()) t.mutable_grad().zero_();
    }
    auto out = pass == 0 ? f() : g();
    if (!weight.defined()) weight = torch::randn_like(out);
    (out * weight).sum().backward();
    outs.push_back(out.detach());
    for (auto& t : leaves) grads[pass].push_back(t.grad().clone());
  }
  expect_close(outs[0], outs[1]);
  for (size_t i = 0; i < leaves.size(); ++i) expect_close(grads[0][i], grads[1][i]);
}

TEST(GraphOps, EdgeFirstLayerMatchesConcatThenLinear) {
  torch::manual_seed(2);
  const int64_t n = 23, e = 150, c = 19, k = 4;
  auto index = EdgeIndex::from_pairs(random_pairs(n, e), n);
  auto base = torch::randn({e, c}, torch::requires_grad());
  auto features = torch::randn({e, k}, torch::requires_grad());
  auto weight = torch::randn({c, k}, torch::requires_grad());
  auto bias = torch::randn({c}, torch::requires_grad());
  auto a = torch::randn({n, c}, torch::requires_grad());
  auto b = torch::randn({n, c}, torch::requires_grad());
  expect_same_function(
      {base, features, weight, bias, a, b},
      [&] { return edge_first_layer(base, features, weight, bias, a, b, index); },
      [&] {
        return torch::relu(base + torch::addmm(bias, features, weight.t()) +
                           a.index_select(0, index.senders) + b.index_select(0, index.receivers));
      });
  // Without a base tensor.
  expect_same_function(
      {features, weight, bias, a, b},
      [&] { return edge_first_layer(torch::Tensor(), features, weight, bias, a, b, index); },
      [&] {
        return torch::relu(torch::addmm(bias, features, weight.t()) +
                           a.index_select(0, index.senders) + b.index_select(0, index.receivers));
      });
}

TEST(GraphOps, LinearMatchesAddmm) {
  torch::manual_seed(6);
  // Enough rows to split the GEMMs over threads, and a strided weight view.
  auto x = torch::randn({1000, 7}, torch::requires_grad());
  auto w_full = torch::randn({9, 12}, torch::requires_grad());
  auto bias = torch::randn({9}, torch::requires_grad());
  auto w = [&] { return w_full.narrow(1, 3, 7); };
  for (bool relu : {false, true}) {
    expect_same_function(
        {x, w_full, bias}, [&] { return linear(x, w(), bias, relu); },
        [&] {
          auto y = torch::addmm(bias, x, w().t());
          return relu ? torch::relu(y) : y;
        });
    expect_same_function(
        {x, w_full}, [&] { return linear(x, w(), {}, relu); },
        [&] {
          auto y = x.mm(w().t());
          return relu ? torch::relu(y) : y;
        });
  }
}

// The float32 products run in oneDNN (whose kernels follow the CPU's instruction sets, not a
// BLAS's table of CPU models); training records this name in train_stats.json.
TEST(GraphOps, FloatProductsNameTheirLibraryAndInstructionSet) {
  const std::string name = matmul_library();
  EXPECT_EQ(name.rfind("oneDNN ", 0), 0u) << name;
  EXPECT_NE(name.find(" sgemm, "), std::string::npos) << name;
}

// bfloat16 products (MatmulPrecision): linear's value and gradients, and the fused inference
// kernel, within bfloat16's rounding of the float32 ones (8 significant bits: a relative error of
// ~0.4 % per operand), but not equal to them (the products did run in bfloat16); the backward
// keeps the precision its forward ran with, whatever is set when it runs.
TEST(GraphOps, Bf16ProductsStayWithinBf16RoundingOfFloat32) {
  torch::manual_seed(11);
  auto x = torch::randn({600, 64}, torch::requires_grad());
  auto w = torch::randn({48, 64}, torch::requires_grad());
  auto bias = torch::randn({48}, torch::requires_grad());
  auto run = [&](MatmulPrecision p) {
    set_matmul_precision(p);
    auto y = linear(x, w, bias, true);
    set_matmul_precision(MatmulPrecision::kFloat32);  // backward must not read this
    auto g = torch::autograd::grad({(y * y).sum()}, {x, w});
    return std::vector<torch::Tensor>{y.detach(), g[0], g[1]};
  };
  const auto f32 = run(MatmulPrecision::kFloat32);
  const auto b16 = run(MatmulPrecision::kBFloat16);
  EXPECT_EQ(matmul_precision(), MatmulPrecision::kFloat32);
  for (size_t i = 0; i < f32.size(); ++i) {
    const double scale = f32[i].abs().max().item<double>();
    const double diff = (b16[i] - f32[i]).abs().max().item<double>();
    EXPECT_LT(diff, 0.03 * scale) << "output " << i;
    EXPECT_GT(diff, 1e-6 * scale) << "output " << i << ": no bfloat16 rounding seen";
  }
  // The fused inference edge MLP (tiles of 256 edges) and mlp_inference.
  const int64_t n = 61, e = 700, c = 24;
  auto index = EdgeIndex::from_pairs(random_pairs(n, e), n);
  auto f = torch::randn({e, 3});
  auto w1 = torch::randn({c, 3}), b1 = torch::randn({c});
  auto a = torch::randn({n, c}), b = torch::randn({n, c});
  auto w2 = torch::randn({c, c}) / 5, b2 = torch::randn({c});
  auto w3 = torch::randn({c, c}) / 5, b3 = torch::randn({c});
  torch::NoGradGuard no_grad;
  const auto fused32 = edge_mlp_segment_sum(f, w1, b1, a, b, w2, b2, w3, b3, index);
  set_matmul_precision(MatmulPrecision::kBFloat16);
  const auto fused16 = edge_mlp_segment_sum(f, w1, b1, a, b, w2, b2, w3, b3, index);
  const auto mlp16 = mlp_inference({a}, {{w2, b2, true}, {w3, b3, false}}, false, {});
  set_matmul_precision(MatmulPrecision::kFloat32);
  const auto mlp32 = mlp_inference({a}, {{w2, b2, true}, {w3, b3, false}}, false, {});
  for (const auto& [lo, hi] : {std::make_pair(fused16, fused32), std::make_pair(mlp16, mlp32)}) {
    const double scale = hi.abs().max().item<double>();
    const double diff = (lo - hi).abs().max().item<double>();
    EXPECT_LT(diff, 0.05 * scale);
    EXPECT_GT(diff, 1e-6 * scale);
  }
}

// Inference MLPs: each worker takes its rows through every layer, the first layer summed over
// column parts; the same values as linear() layer by layer on the concatenated input.
TEST(GraphOps, MlpInferenceMatchesLayerByLayer) {
  torch::manual_seed(8);
  // Widths 12 -> 20 -> 9 -> 16 (hidden widths differ: the buffers are reused at other shapes).
  const std::vector<int64_t> widths = {12, 20, 9, 16};
  std::vector<DenseLayer> layers;
  for (size_t l = 0; l + 1 < widths.size(); ++l)
    layers.push_back({torch::randn({widths[l + 1], widths[l]}) / 3, torch::randn({widths[l + 1]}),
                      l + 2 < widths.size()});
  for (int64_t rows : {1, 31, 40, 300, 1000}) {
    SCOPED_TRACE("rows " + std::to_string(rows));
    const auto x = torch::randn({rows, 12});
    for (bool norm : {false, true}) {
      auto reference = x;
      for (const auto& l : layers) {
        reference = torch::addmm(l.bias, reference, l.weight.t());
        if (l.relu) reference = torch::relu(reference);
      }
      if (norm) reference = torch::layer_norm(reference, {16});
      torch::NoGradGuard no_grad;
      expect_close(mlp_inference({x}, layers, norm), reference);
      // The same input in three column parts, one of them a strided view.
      const auto wide = torch::randn({rows, 20});
      wide.narrow(1, 3, 5).copy_(x.narrow(1, 0, 5));
      expect_close(
          mlp_inference({wide.narrow(1, 3, 5), x.narrow(1, 5, 4), x.narrow(1, 9, 3)}, layers, norm),
          reference);
    }
  }
  // A sparse part (rows listed, the others zero) gives what its dense, zero-filled form gives.
  for (int64_t rows : {7, 64, 500}) {
    const auto v = torch::randn({rows, 9});
    auto dense = torch::zeros({rows, 3});
    const auto at = torch::arange(0, rows, 3, torch::kInt64);  // every third row
    const auto values = torch::randn({at.size(0), 3});
    dense.index_copy_(0, at, values);
    torch::NoGradGuard no_grad;
    for (bool norm : {false, true}) {
      expect_close(mlp_inference({v, values}, layers, norm, {torch::Tensor(), at}),
                   mlp_inference({v, dense}, layers, norm));
      expect_close(mlp_inference({v, values.narrow(0, 0, 0)}, layers, norm,
                                 {torch::Tensor(), at.narrow(0, 0, 0)}),
                   mlp_inference({v, torch::zeros({rows, 3})}, layers, norm));
    }
    EXPECT_THROW(mlp_inference({v, values}, layers, false, {torch::Tensor(), at.flip(0)}),
                 InputError);  // not ascending
    EXPECT_THROW(mlp_inference({v, values}, layers, false, {at, torch::Tensor()}), InputError);
  }
  // linear() without gradients takes the same path: one layer, with and without bias.
  const auto x = torch::randn({100, 12});
  const auto& first = layers[0];
  torch::NoGradGuard no_grad;
  expect_close(linear(x, first.weight, first.bias, true),
               torch::relu(torch::addmm(first.bias, x, first.weight.t())));
  expect_close(linear(x, first.weight, {}, false), x.mm(first.weight.t()));
  EXPECT_THROW(mlp_inference({torch::randn({5, 11})}, layers, false), InputError);
  EXPECT_THROW(mlp_inference({x, torch::randn({99, 1})}, layers, false), InputError);
  EXPECT_THROW(mlp_inference({x}, {{first.weight, {}, false}}, true), InputError);
}

TEST(GraphOps, LayerNormSegmentSumMatchesLayerNormThenIndexAdd) {
  torch::manual_seed(3);
  const int64_t n = 17, e = 120, c = 33;
  auto index = EdgeIndex::from_pairs(random_pairs(n, e), n);
  auto x = (3 * torch::randn({e, c}) + 1).requires_grad_();
  auto bias = torch::randn({c}, torch::requires_grad());
  expect_same_function(
      {x, bias}, [&] { return layer_norm_segment_sum(x, bias, index); },
      [&] {
        return torch::zeros({n, c}).index_add(0, index.receivers, torch::layer_norm(x + bias, {c}));
      });
}

TEST(GraphOps, FusedInferenceEdgeMlpMatchesTheComposedKernels) {
  torch::manual_seed(5);
  // 700 edges: several tiles of 256 and, with 2 threads, two receiver ranges; node 0 of the
  // 61 has no incoming edge; k = 0 has no edge features at all.
  const int64_t n = 61, e = 700, c = 24;
  auto pairs = random_pairs(n - 1, e) + 1;
  auto index = EdgeIndex::from_pairs(pairs, n);
  for (int64_t k : {3, 0}) {
    auto f = torch::randn({e, k});
    auto w1 = torch::randn({c, k}), b1 = torch::randn({c});
    auto a = torch::randn({n, c}), b = torch::randn({n, c});
    auto w2 = torch::randn({c, c}) / 5, b2 = torch::randn({c});
    auto w3 = torch::randn({c, c}) / 5, b3 = torch::randn({c});
    torch::NoGradGuard no_grad;
    auto h1 = edge_first_layer(torch::Tensor(), f, w1, b1, a, b, index);
    auto composed =
        layer_norm_segment_sum(linear(linear(h1, w2, b2, true), w3, {}, false), b3, index);
    auto fused = edge_mlp_segment_sum(f, w1, b1, a, b, w2, b2, w3, b3, index);
    expect_close(fused, composed);
    EXPECT_EQ(fused[0].abs().max().item<float>(), 0.0f);
  }
  // With gradients on, inputs that need them are refused (the kernel has no backward).
  auto a = torch::randn({n, c}, torch::requires_grad());
  EXPECT_THROW(edge_mlp_segment_sum(torch::randn({e, 0}), torch::randn({c, 0}), torch::randn({c}),
                                    a, a, torch::randn({c, c}), torch::randn({c}),
                                    torch::randn({c, c}), torch::randn({c}), index),
               InputError);
}

// Few edges: the endpoint terms projected per edge (a [E, C], no b) give the per-node result.
TEST(GraphOps, FusedEdgeMlpTakesEndpointTermsPerEdge) {
  torch::manual_seed(9);
  const int64_t n = 50, c = 16, k = 3;
  for (int64_t e : {0, 1, 7, 70, 600}) {
    SCOPED_TRACE("edges " + std::to_string(e));
    auto index = EdgeIndex::from_pairs(random_pairs(n, e), n);
    auto f = torch::randn({e, k});
    auto w1 = torch::randn({c, k}), b1 = torch::randn({c});
    auto a = torch::randn({n, c}), b = torch::randn({n, c});
    auto w2 = torch::randn({c, c}) / 4, b2 = torch::randn({c});
    auto w3 = torch::randn({c, c}) / 4, b3 = torch::randn({c});
    torch::NoGradGuard no_grad;
    const auto per_node = edge_mlp_segment_sum(f, w1, b1, a, b, w2, b2, w3, b3, index);
    const auto ends = a.index_select(0, index.senders) + b.index_select(0, index.receivers);
    expect_close(edge_mlp_segment_sum(f, w1, b1, ends, {}, w2, b2, w3, b3, index), per_node);
    // Per-edge terms have one row per edge; the edge-latent kernel needs per-node ones.
    EXPECT_THROW(
        edge_mlp_segment_sum(f, w1, b1, torch::randn({e + 1, c}), {}, w2, b2, w3, b3, index),
        InputError);
  }
  auto index = EdgeIndex::from_pairs(random_pairs(n, 20), n);
  torch::NoGradGuard no_grad;
  torch::Tensor next;
  EXPECT_THROW(
      edge_latent_update(torch::randn({20, c}), torch::randn({c, c}), torch::randn({c}),
                         torch::randn({20, c}), {}, torch::randn({c, c}), torch::randn({c}),
                         torch::randn({c, c}), torch::randn({c}), index, next),
      InputError);
}

TEST(GraphOps, FusedEdgeLatentUpdateMatchesTheComposedKernels) {
  torch::manual_seed(6);
  // 900 edges: several tiles and, with 2 threads, two receiver ranges; node 0 receives nothing.
  const int64_t n = 70, e = 900, c = 20;
  auto index = EdgeIndex::from_pairs(random_pairs(n - 1, e) + 1, n);
  auto latent = torch::randn({e, c});
  auto w1 = torch::randn({c, c}) / 4, b1 = torch::randn({c});
  auto a = torch::randn({n, c}), b = torch::randn({n, c});
  auto w2 = torch::randn({c, c}) / 5, b2 = torch::randn({c});
  auto w3 = torch::randn({c, c}) / 5, b3 = torch::randn({c});
  torch::NoGradGuard no_grad;
  // The training path of EdgeLatentBlock (models/networks.cpp).
  auto base = linear(latent, w1, {}, false);
  auto h1 = edge_first_layer(base, torch::empty({e, 0}), torch::empty({c, 0}), b1, a, b, index);
  auto y = at::layer_norm(linear(linear(h1, w2, b2, true), w3, b3, false), {c});
  auto composed = segment_sum(y, index);
  torch::Tensor next;
  auto fused = edge_latent_update(latent, w1, b1, a, b, w2, b2, w3, b3, index, next);
  expect_close(fused, composed);
  expect_close(next, latent + y);
  EXPECT_EQ(fused[0].abs().max().item<float>(), 0.0f);
  // Edge latents of another width than the node latents are refused.
  EXPECT_THROW(edge_latent_update(torch::randn({e, c + 1}), torch::randn({c, c + 1}), b1, a, b, w2,
                                  b2, w3, b3, index, next),
               InputError);
}

TEST(GraphOps, SegmentSumMatchesIndexAdd) {
  torch::manual_seed(4);
  const int64_t n = 11, e = 60, c = 5;
  auto index = EdgeIndex::from_pairs(random_pairs(n, e), n);
  auto x = torch::randn({e, c}, torch::requires_grad());
  auto weight = torch::randn({n, c});
  auto out = segment_sum(x, index);
  (out * weight).sum().backward();
  auto ref = torch::zeros({n, c}).index_add(0, index.receivers, x);
  expect_close(out, ref);
  expect_close(x.grad(), weight.index_select(0, index.receivers));
}

TEST(GraphOps, EmptyEdgeSetGivesZeros) {
  auto index = EdgeIndex::empty(4);
  auto out = layer_norm_segment_sum(torch::zeros({0, 3}), torch::zeros({3}), index);
  EXPECT_TRUE(torch::equal(out, torch::zeros({4, 3})));
}

// Dense transition matrix over all fine nodes: M[j, i] = down_weight of edge i -> j.
torch::Tensor dense_weights(const testing::ReferenceLevel& fine,
                            const testing::ReferenceLevel& coarse) {
  const auto& g = fine.graph;
  auto m = torch::zeros({g.num_nodes, g.num_nodes});
  for (int64_t i = 0; i < g.num_nodes; ++i) {
    for (int64_t p = g.offsets[i]; p < g.offsets[i + 1]; ++p) {
      m[g.targets[p]][i] = coarse.down_weight[p];
    }
  }
  return m;
}

TEST(Transitions, MatchDenseFormula) {
  torch::manual_seed(5);
  auto mesh = testing::grid_mesh(7, 5);
  auto graph = testing::reference_multilevel(mesh.graph, 4);
  auto hierarchy = testing::reference_tensors(graph);
  ASSERT_EQ(hierarchy.num_levels(), 4);
  for (int k = 0; k + 1 < 4; ++k) {
    const auto& fine = graph.levels[k];
    const auto& coarse = graph.levels[k + 1];
    auto pooled = torch::tensor(coarse.pooled, torch::kInt64);
    auto m = dense_weights(fine, coarse);
    auto v = torch::randn({fine.num_nodes(), 6}, torch::requires_grad());
    auto down = transition_down(v, hierarchy.transitions[k + 1]);
    expect_close(down, m.mm(v).index_select(0, pooled));
    auto u = torch::randn({coarse.num_nodes(), 6}, torch::requires_grad());
    auto unpooled = torch::zeros({fine.num_nodes(), 6}).index_copy(0, pooled, u);
    auto up = transition_up(u, hierarchy.transitions[k + 1]);
    expect_close(up, m.t().mm(unpooled));
    // Adjoint gradients: d(down)/dv = Dᵀ, d(up)/du = D.
    auto gd = torch::randn_like(down), gu = torch::randn_like(up);
    (down * gd).sum().backward();
    (up * gu).sum().backward();
    auto gd_full = torch::zeros({fine.num_nodes(), 6}).index_copy(0, pooled, gd);
    expect_close(v.grad(), m.t().mm(gd_full));
    expect_close(u.grad(), m.mm(gu).index_select(0, pooled));
  }
}

// One level convention in preprocess and models: transition k belongs to its coarse level k.
TEST(Transitions, IndexIsTheCoarseLevel) {
  auto mesh = testing::grid_mesh(9, 8);
  auto graph = testing::reference_multilevel(mesh.graph, 4);
  const MultilevelTensors single = testing::reference_tensors(graph);
  const MultilevelTensors merged = merge_multilevel_tensors({&single, &single});
  for (const MultilevelTensors* h : {&single, &merged}) {
    const MultilevelTensors& hierarchy = *h;
    ASSERT_EQ(hierarchy.transitions.size(), 4u);
    EXPECT_EQ(hierarchy.transitions[0].coarse_nodes, 0);
    EXPECT_EQ(hierarchy.transitions[0].fine_nodes, 0);
    for (int k = 1; k < 4; ++k) {
      EXPECT_EQ(hierarchy.transitions[k].fine_nodes, hierarchy.num_nodes(k - 1)) << k;
      EXPECT_EQ(hierarchy.transitions[k].coarse_nodes, hierarchy.num_nodes(k)) << k;
    }
  }
}

TEST(Transitions, DownKeepsConstantFieldUpConservesSum) {
  auto mesh = testing::grid_mesh(9, 8);
  auto graph = testing::reference_multilevel(mesh.graph, 5);
  auto hierarchy = testing::reference_tensors(graph);
  for (int k = 1; k < 5; ++k) {
    const auto& t = hierarchy.transitions[k];
    auto ones = torch::full({t.fine_nodes, 3}, 2.5f);
    // Receiver weights sum to 1, so a constant field is reproduced on the coarse level.
    expect_close(transition_down(ones, t), torch::full({t.coarse_nodes, 3}, 2.5f));
    // Up distributes each coarse value over its fine neighbours with weights summing to 1.
    auto u = torch::rand({t.coarse_nodes, 3});
    expect_close(transition_up(u, t).sum(0), u.sum(0));
    expect_close(transition_up(torch::full({t.coarse_nodes, 3}, 2.5f), t).sum(0),
                 torch::full({3}, 2.5f * t.coarse_nodes));
  }
}

TEST(MultilevelTensors, MergeIsBlockDiagonal) {
  auto m1 = testing::grid_mesh(5, 4), m2 = testing::grid_mesh(3, 6);
  auto h1 = testing::reference_tensors(testing::reference_multilevel(m1.graph, 3));
  auto h2 = testing::reference_tensors(testing::reference_multilevel(m2.graph, 3));
  auto merged = merge_multilevel_tensors({&h1, &h2});
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(merged.num_nodes(k), h1.num_nodes(k) + h2.num_nodes(k));
    EXPECT_EQ(merged.node_offsets[k],
              (std::vector<int64_t>{0, h1.num_nodes(k), h1.num_nodes(k) + h2.num_nodes(k)}));
    const auto& e = merged.edge_sets[k][0];
    EXPECT_EQ(e.num_edges(), h1.edge_sets[k][0].num_edges() + h2.edge_sets[k][0].num_edges());
    auto x = torch::randn({merged.num_nodes(k), 4});
    auto x1 = x.slice(0, 0, h1.num_nodes(k)), x2 = x.slice(0, h1.num_nodes(k));
    expect_close(
        segment_sum(x.index_select(0, e.senders), e),
        torch::cat(
            {segment_sum(x1.index_select(0, h1.edge_sets[k][0].senders), h1.edge_sets[k][0]),
             segment_sum(x2.index_select(0, h2.edge_sets[k][0].senders), h2.edge_sets[k][0])}));
    if (k < 2) {
      expect_close(transition_down(x, merged.transitions[k + 1]),
                   torch::cat({transition_down(x1, h1.transitions[k + 1]),
                               transition_down(x2, h2.transitions[k + 1])}));
    }
  }
  auto h3 = testing::reference_tensors(testing::reference_multilevel(m2.graph, 2));
  EXPECT_THROW(merge_multilevel_tensors({&h1, &h3}), InputError);
}

// MultilevelTensorCache (src/pipeline/graphs/multilevel_tensors.hpp) is tested in tests/pipeline.
TEST(MultilevelTensors, ExtraEdgeSets) {
  auto mesh = testing::grid_mesh(4, 4);
  const auto h = testing::reference_tensors(testing::reference_multilevel(mesh.graph, 3));
  auto contact = torch::tensor({0, 15, 15, 0}, torch::kInt64).reshape({2, 2});
  auto with = h.with_edge_sets({{contact}});
  ASSERT_EQ(with.edge_sets[0].size(), 2u);
  EXPECT_EQ(with.edge_sets[0][1].num_edges(), 2);
  EXPECT_EQ(with.edge_sets[2][1].num_edges(), 0);
  EXPECT_EQ(h.edge_sets[0].size(), 1u);
  EdgeList level0, level1;
  level0.data = {0, 15, 15, 0, 3, 12};
  level1.data = {1, 2};
  auto from_lists = h.with_edge_sets(std::vector<EdgeList>{level0, level1});
  EXPECT_EQ(from_lists.edge_sets[0][1].num_edges(), 3);
  EXPECT_EQ(from_lists.edge_sets[1][1].num_edges(), 1);
  EXPECT_EQ(from_lists.edge_sets[2][1].num_edges(), 0);
  level1.data = {1, 99};
  EXPECT_THROW(h.with_edge_sets(std::vector<EdgeList>{level0, level1}), InputError);
}

}  // namespace
}  // namespace bsms
