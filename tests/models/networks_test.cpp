#include "models/networks.hpp"

#include <gtest/gtest.h>
#include <torch/torch.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <set>
#include <string>

#include "core/error.hpp"
#include "models/checkpoint.hpp"
#include "models/graph_ops.hpp"
#include "tests/models/graph_fixtures.hpp"
#include "tests/temp_dir.hpp"

namespace bsms {
namespace {

// Mesh edges use mesh X and world x; contact edges world x only (docs/design.md "Models").
GraphModelOptions lagrangian_options(int levels, int64_t latent = 16) {
  GraphModelOptions o;
  o.input_size = 3;
  o.output_size = 2;
  o.latent = latent;
  o.position_dims = {2, 2};
  o.edge_set_fields = {{0, 1}, {1}};
  o.num_levels = levels;
  o.message_passing_steps = 3;
  return o;
}

struct Problem {
  MultilevelTensors graph;
  torch::Tensor nodes;
  std::vector<torch::Tensor> positions;
};

// Grid with random inputs, a perturbed world position and random contact edges on every level.
Problem make_problem(int64_t nx, int64_t ny, int levels, bool contacts) {
  auto mesh = testing::grid_mesh(nx, ny);
  Problem p;
  p.graph = testing::reference_tensors(testing::reference_multilevel(mesh.graph, levels));
  if (contacts) {
    std::vector<std::vector<torch::Tensor>> extra;
    for (int k = 0; k < levels; ++k) {
      extra.push_back({torch::randint(0, p.graph.num_nodes(k), {5, 2}, torch::kInt64)});
    }
    p.graph = p.graph.with_edge_sets(extra);
  }
  const int64_t n = nx * ny;
  p.nodes = torch::randn({n, 3});
  p.positions = {mesh.positions / 4, mesh.positions / 4 + 0.1 * torch::randn({n, 2})};
  return p;
}

std::vector<std::shared_ptr<GraphModel>> both_models(int levels, int64_t latent = 16) {
  return {std::make_shared<BsmsGnn>(lagrangian_options(levels, latent)),
          std::make_shared<MeshGraphNets>(lagrangian_options(levels, latent))};
}

double max_rel_diff(const torch::Tensor& a, const torch::Tensor& b) {
  return (a - b).abs().max().item<double>() / (1.0 + b.abs().max().item<double>());
}

TEST(Networks, OutputShapeAndGradientsReachEveryParameter) {
  torch::manual_seed(10);
  auto p = make_problem(7, 6, 3, true);
  for (auto& model : both_models(3)) {
    auto out = model->forward(p.nodes, p.positions, p.graph);
    EXPECT_EQ(out.sizes(), (std::vector<int64_t>{42, 2}));
    out.square().sum().backward();
    for (const auto& param : model->named_parameters()) {
      ASSERT_TRUE(param.value().grad().defined()) << param.key();
      EXPECT_GT(param.value().grad().abs().sum().item<double>(), 0.0) << param.key();
    }
  }
}

// mp_per_level = 2 keeps every parameter name of the one-block model (old checkpoints load) and
// adds one block per level down and up and one at the bottom; with the extra blocks' node updates
// zeroed (they are residual) it computes exactly what the one-block model computes.
TEST(Networks, MoreBlocksPerLevelExtendTheOneBlockModel) {
  torch::manual_seed(12);
  const int levels = 3;
  auto p = make_problem(7, 6, levels, true);
  BsmsGnn one(lagrangian_options(levels));
  auto options = lagrangian_options(levels);
  options.mp_per_level = 2;
  BsmsGnn two(options);
  const auto one_params = one.named_parameters();
  auto two_params = two.named_parameters();
  int64_t extra = 0;
  {
    torch::NoGradGuard no_grad;
    for (const auto& param : two_params) {
      if (const auto* same = one_params.find(param.key())) {
        param.value().copy_(*same);
      } else {
        extra += param.value().numel();
        const auto& key = param.key();
        ASSERT_TRUE(key.rfind("down_0_1.", 0) == 0 || key.rfind("down_1_1.", 0) == 0 ||
                    key.rfind("up_0_1.", 0) == 0 || key.rfind("up_1_1.", 0) == 0 ||
                    key.rfind("bottom_1.", 0) == 0)
            << key;
        if (key.find(".node_mlp.third.") != std::string::npos) param.value().zero_();
      }
    }
  }
  for (const auto& param : one_params) EXPECT_TRUE(two_params.contains(param.key())) << param.key();
  int64_t block = 0;
  for (const auto& param : one.named_parameters()) {
    if (param.key().rfind("bottom.", 0) == 0) block += param.value().numel();
  }
  EXPECT_EQ(extra, (2 * (levels - 1) + 1) * block);
  torch::NoGradGuard no_grad;
  auto a = one.forward(p.nodes, p.positions, p.graph);
  auto b = two.forward(p.nodes, p.positions, p.graph);
  EXPECT_LT(max_rel_diff(b, a), 1e-6);
  // With the extra blocks live the output changes.
  for (auto& param : two.named_parameters()) {
    if (param.key() == "bottom_1.node_mlp.third.weight") param.value().normal_(0.0, 0.1);
  }
  EXPECT_GT(max_rel_diff(two.forward(p.nodes, p.positions, p.graph), a), 1e-4);
  options.mp_per_level = 0;
  EXPECT_THROW(BsmsGnn{options}, InputError);
}

// Per-level block counts: level k gets its count of blocks down and up, the last level its count
// at the bottom; a uniform list is the mp_per_level model itself (same parameter names and sizes,
// same output); a list of the wrong length or with a zero is refused.
TEST(Networks, PerLevelBlockCounts) {
  torch::manual_seed(13);
  const int levels = 3;
  auto p = make_problem(7, 6, levels, true);
  auto options = lagrangian_options(levels);
  options.mp_per_level_list = {3, 1, 2};
  BsmsGnn model(options);
  std::set<std::string> blocks;
  for (const auto& param : model.named_parameters()) {
    const auto& key = param.key();
    if (key.rfind("down_", 0) == 0 || key.rfind("up_", 0) == 0 || key.rfind("bottom", 0) == 0)
      blocks.insert(key.substr(0, key.find('.')));
  }
  EXPECT_EQ(blocks, (std::set<std::string>{"down_0", "down_0_1", "down_0_2", "up_0", "up_0_1",
                                           "up_0_2", "down_1", "up_1", "bottom", "bottom_1"}));
  EXPECT_EQ(model.forward(p.nodes, p.positions, p.graph).size(0), p.nodes.size(0));

  auto uniform = lagrangian_options(levels);
  uniform.mp_per_level_list = {2, 2, 2};
  auto two = lagrangian_options(levels);
  two.mp_per_level = 2;
  torch::manual_seed(5);
  BsmsGnn a(uniform);
  torch::manual_seed(5);
  BsmsGnn b(two);
  const auto pa = a.named_parameters(), pb = b.named_parameters();
  ASSERT_EQ(pa.size(), pb.size());
  for (const auto& param : pa) {
    ASSERT_TRUE(pb.contains(param.key())) << param.key();
    EXPECT_TRUE(torch::equal(param.value(), pb[param.key()])) << param.key();
  }
  torch::NoGradGuard no_grad;
  EXPECT_TRUE(torch::equal(a.forward(p.nodes, p.positions, p.graph),
                           b.forward(p.nodes, p.positions, p.graph)));

  options.mp_per_level_list = {2, 1};
  EXPECT_THROW(BsmsGnn{options}, InputError);
  options.mp_per_level_list = {2, 0, 1};
  EXPECT_THROW(BsmsGnn{options}, InputError);
}

TEST(Networks, MissingContactSetCountsAsEmpty) {
  torch::manual_seed(11);
  auto p = make_problem(5, 5, 2, false);
  for (auto& model : both_models(2)) {
    EXPECT_EQ(model->forward(p.nodes, p.positions, p.graph).size(0), 25);
  }
}

TEST(Networks, EdgeNormalizerStatisticsAreThoseOfTheEdgeFeatures) {
  torch::manual_seed(13);
  const int levels = 2;
  auto p = make_problem(6, 5, levels, false);  // no contact edges: set 1 is empty everywhere
  for (int which = 0; which < 2; ++which) {
    GraphModelOptions o = lagrangian_options(levels);
    GraphModelOptions plain = o;
    o.edge_normalizer = true;
    std::shared_ptr<GraphModel> model, raw;
    if (which == 0) {
      model = std::make_shared<BsmsGnn>(o);
      raw = std::make_shared<BsmsGnn>(plain);
    } else {
      model = std::make_shared<MeshGraphNets>(o);
      raw = std::make_shared<MeshGraphNets>(plain);
    }
    const int model_levels = which == 0 ? levels : 1;
    EXPECT_EQ(model->edge_normalizer_sums().size(), static_cast<size_t>(3 * model_levels * 2));
    EXPECT_TRUE(raw->edge_normalizer_sums().empty());
    // Same parameters; before any statistics the normalizers leave the features raw.
    {
      torch::NoGradGuard no_grad;
      auto from = raw->named_parameters();
      for (auto& item : model->named_parameters()) item.value().copy_(from[item.key()]);
    }
    EXPECT_LT(max_rel_diff(model->forward(p.nodes, p.positions, p.graph),
                           raw->forward(p.nodes, p.positions, p.graph)),
              1e-6);
    model->accumulate_edge_statistics(p.positions, p.graph);
    model->accumulate_edge_statistics(p.positions, p.graph);
    auto buffers = model->named_buffers();
    // Level 0, mesh edges: the sums are those of the features, twice.
    const EdgeIndex& mesh_edges = p.graph.edge_sets[0][0];
    const auto f = edge_features(p.positions, {0, 1}, mesh_edges).to(torch::kFloat64);
    EXPECT_EQ(buffers["edge_normalizer_0_0.count"].item<double>(), 2.0 * mesh_edges.num_edges());
    EXPECT_LT((buffers["edge_normalizer_0_0.sum"] - 2 * f.sum(0)).abs().max().item<double>(),
              1e-9 * (1 + f.abs().sum().item<double>()));
    EXPECT_LT((buffers["edge_normalizer_0_0.sum_squares"] - 2 * f.square().sum(0))
                  .abs()
                  .max()
                  .item<double>(),
              1e-9 * (1 + f.square().sum().item<double>()));
    for (int k = 0; k < model_levels; ++k) {
      const std::string prefix = "edge_normalizer_" + std::to_string(k) + "_";
      EXPECT_EQ(buffers[prefix + "0.count"].item<double>(),
                2.0 * p.graph.edge_sets[k][0].num_edges());
      EXPECT_EQ(buffers[prefix + "1.count"].item<double>(), 0.0);  // never saw a contact edge
    }
    // Now the model sees standardised features: other outputs than the raw model's.
    EXPECT_GT(max_rel_diff(model->forward(p.nodes, p.positions, p.graph),
                           raw->forward(p.nodes, p.positions, p.graph)),
              1e-3);
    // A contact edge appearing later stays raw in its never-accumulated set: finite outputs.
    auto q = make_problem(6, 5, levels, true);
    q.positions = p.positions;
    q.nodes = p.nodes;
    EXPECT_TRUE(torch::isfinite(model->forward(q.nodes, q.positions, q.graph)).all().item<bool>());
  }
}

TEST(Networks, ProjectionEqualsConcatFormulation) {
  torch::manual_seed(12);
  auto p = make_problem(8, 7, 3, true);
  for (auto& model : both_models(3, 32)) {
    std::vector<torch::Tensor> outputs, grads;
    for (auto mode : {EdgeMlpMode::kProjection, EdgeMlpMode::kConcat}) {
      model->zero_grad();
      model->set_edge_mlp_mode(mode);
      auto out = model->forward(p.nodes, p.positions, p.graph);
      (out * torch::cos(out)).sum().backward();
      outputs.push_back(out.detach());
      std::vector<torch::Tensor> g;
      for (const auto& param : model->parameters()) g.push_back(param.grad().flatten());
      grads.push_back(torch::cat(g));
    }
    EXPECT_LT(max_rel_diff(outputs[0], outputs[1]), 1e-5);
    EXPECT_LT(max_rel_diff(grads[0], grads[1]), 1e-5);
  }
}

// edge_features in one pass equals its tensor formula: [Δp, |Δp|] per field, then the stretch
// (0 on edges whose reference nodes coincide), float32 and float64.
TEST(EdgeFeatures, OnePassMatchesTheTensorFormula) {
  torch::manual_seed(21);
  const int64_t n = 40;
  auto pairs = torch::randint(0, n, {3000, 2}, torch::kInt64);  // with self loops: |Δp| = 0
  const EdgeIndex edges = EdgeIndex::from_pairs(pairs, n);
  for (auto dtype : {torch::kFloat32, torch::kFloat64}) {
    auto X = torch::randn({n, 2}, dtype);
    X[1] = X[0];  // a degenerate edge 0 - 1 reads as unstretched
    const auto x = X * 1.1 + 0.05 * torch::randn({n, 2}, dtype);
    const auto w = torch::randn({n, 3}, dtype);
    const EdgeStretch stretch{0, 1, 4.0};
    const std::vector<torch::Tensor> positions = {X, x, w};
    auto delta = [&](const torch::Tensor& p) {
      return p.index_select(0, edges.senders) - p.index_select(0, edges.receivers);
    };
    auto expected = [&](const std::vector<int64_t>& fields, bool with_stretch) {
      std::vector<torch::Tensor> parts;
      for (int64_t f : fields) {
        const auto d = delta(positions[f]);
        parts.push_back(d);
        parts.push_back(d.norm(2, {1}, true));
      }
      if (with_stretch) {
        const auto rest = delta(X).norm(2, {1}, true), now = delta(x).norm(2, {1}, true);
        parts.push_back(
            torch::where(rest > 0, now / rest.clamp_min(1e-30) - 1, torch::zeros_like(rest)) * 4.0);
      }
      return torch::cat(parts, 1);
    };
    const double tol = dtype == torch::kFloat32 ? 1e-5 : 1e-12;
    for (const auto& fields : std::vector<std::vector<int64_t>>{{0, 1}, {1}, {2, 0}, {}}) {
      for (bool with_stretch : {true, false}) {
        if (fields.empty() && !with_stretch) continue;
        const auto got =
            edge_features(positions, fields, edges, with_stretch ? stretch : EdgeStretch{});
        const auto want = expected(fields, with_stretch);
        ASSERT_EQ(got.sizes(), want.sizes());
        EXPECT_EQ(got.scalar_type(), dtype);
        EXPECT_LT(max_rel_diff(got, want), tol);
      }
    }
  }
  EXPECT_THROW(edge_features({torch::randn({n, 2})}, {1}, edges), InputError);
  EXPECT_THROW(
      edge_features({torch::randn({n, 2}), torch::randn({n, 2}, torch::kFloat64)}, {0, 1}, edges),
      InputError);
  EXPECT_THROW(edge_features({torch::randn({n - 1, 2})}, {0}, edges), InputError);
  EXPECT_THROW(edge_features({torch::randn({n, 2}), torch::randn({n, 3})}, {}, edges,
                             EdgeStretch{0, 1, 1.0}),
               InputError);
}

TEST(Networks, InferenceModeAndThreadCountGiveTheSameOutputs) {
  torch::manual_seed(17);
  auto p = make_problem(30, 20, 4, true);  // enough edges to split kernels over threads
  const int threads = torch::get_num_threads();
  for (auto& model : both_models(4)) {
    auto reference = model->forward(p.nodes, p.positions, p.graph).detach();
    {
      torch::InferenceMode guard;
      EXPECT_LT(max_rel_diff(model->forward(p.nodes, p.positions, p.graph), reference), 1e-6);
    }
    configure_threads(1);
    EXPECT_LT(max_rel_diff(model->forward(p.nodes, p.positions, p.graph), reference), 1e-5);
    configure_threads(threads);
  }
}

TEST(Networks, BatchOfTwoMeshesEqualsEachAlone) {
  torch::manual_seed(13);
  auto p1 = make_problem(6, 5, 3, true);
  auto p2 = make_problem(4, 9, 3, true);
  auto batch = merge_multilevel_tensors({&p1.graph, &p2.graph});
  auto nodes = torch::cat({p1.nodes, p2.nodes});
  std::vector<torch::Tensor> positions;
  for (size_t f = 0; f < 2; ++f)
    positions.push_back(torch::cat({p1.positions[f], p2.positions[f]}));
  for (auto& model : both_models(3)) {
    auto joint = model->forward(nodes, positions, batch);
    auto alone = torch::cat({model->forward(p1.nodes, p1.positions, p1.graph),
                             model->forward(p2.nodes, p2.positions, p2.graph)});
    EXPECT_LT(max_rel_diff(joint, alone), 1e-5);
  }
}

TEST(Networks, OverfitsTinyProblem) {
  torch::manual_seed(14);
  auto p = make_problem(6, 6, 3, false);
  // A target that needs neighbourhood information: the mean of the neighbours' inputs.
  const auto& e = p.graph.edge_sets[0][0];
  auto counts = torch::zeros({36, 1}).index_add_(0, e.receivers, torch::ones({e.num_edges(), 1}));
  auto target =
      (torch::zeros({36, 3}).index_add_(0, e.receivers, p.nodes.index_select(0, e.senders)) /
       counts)
          .slice(1, 0, 2);
  for (auto& model : both_models(3, 32)) {
    torch::optim::Adam adam(model->parameters(), torch::optim::AdamOptions(1e-3));
    // Adam at tiny losses has spikes: compare the best of the last 50 steps with the first.
    double first = 0.0, best_late = 1e30;
    for (int step = 0; step < 300; ++step) {
      adam.zero_grad();
      auto loss = (model->forward(p.nodes, p.positions, p.graph) - target).square().mean();
      loss.backward();
      adam.step();
      if (step == 0) first = loss.item<double>();
      if (step >= 250) best_late = std::min(best_late, loss.item<double>());
    }
    EXPECT_LT(best_late, first / 100.0)
        << model->name() << " first " << first << " best " << best_late;
  }
}

class CheckpointTest : public ::testing::Test {
 protected:
  std::string path(const std::string& name) {
    const auto dir = testing::unique_temp_dir("models_test");
    dirs_.push_back(dir);
    return (dir / name).string();
  }
  void TearDown() override {
    for (const auto& d : dirs_) std::filesystem::remove_all(d);
  }
  std::vector<std::filesystem::path> dirs_;
};

// A model with its normalizers, as training code keeps it.
struct Simulator : torch::nn::Module {
  explicit Simulator(int64_t latent) {
    auto o = lagrangian_options(3, latent);
    net = register_module("net", std::make_shared<BsmsGnn>(o));
    input_norm = register_module("input_norm", std::make_shared<Normalizer>(3));
  }
  std::shared_ptr<BsmsGnn> net;
  std::shared_ptr<Normalizer> input_norm;
};

TEST_F(CheckpointTest, RoundTripGivesIdenticalOutputs) {
  torch::manual_seed(15);
  auto p = make_problem(6, 5, 3, true);
  Simulator a(16);
  a.input_norm->accumulate(3 * p.nodes + 1);
  const auto file = path("model.h5");
  save_module(a, file);
  torch::manual_seed(99);
  Simulator b(16);
  auto before = b.net->forward(b.input_norm->normalize(p.nodes), p.positions, p.graph);
  load_module(b, file);
  auto expected = a.net->forward(a.input_norm->normalize(p.nodes), p.positions, p.graph);
  auto loaded = b.net->forward(b.input_norm->normalize(p.nodes), p.positions, p.graph);
  EXPECT_TRUE(torch::equal(expected, loaded));
  EXPECT_FALSE(torch::equal(before, loaded));
  EXPECT_TRUE(torch::equal(a.input_norm->mean(), b.input_norm->mean()));
}

TEST_F(CheckpointTest, MismatchedShapesThrowNamingFileAndEntry) {
  const auto file = path("small.h5");
  save_module(Simulator(8), file);
  Simulator big(16);
  auto before = big.net->parameters()[0].clone();
  try {
    load_module(big, file);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(file), std::string::npos) << what;
    EXPECT_NE(what.find("net.encoder.first.weight"), std::string::npos) << what;
  }
  EXPECT_TRUE(torch::equal(before, big.net->parameters()[0]));  // untouched on error
  EXPECT_THROW(load_module(big, path("missing.h5")), InputError);
  MeshGraphNets other(lagrangian_options(3, 16));
  const auto other_file = path("mgn.h5");
  save_module(other, other_file);
  EXPECT_THROW(load_module(big, other_file), InputError);
}

TEST(Normalizer, RunningStatisticsMatchWholeData) {
  torch::manual_seed(16);
  Normalizer norm(3, /*max_accumulations=*/2);
  auto x1 = torch::randn({50, 3}) * 2 + 5, x2 = torch::randn({70, 3}) * 0.5 - 1;
  auto x3 = torch::randn({10, 3}) * 100;
  norm.accumulate(x1);
  norm.accumulate(x2);
  norm.accumulate(x3);  // ignored: max_accumulations reached
  auto all = torch::cat({x1, x2}).to(torch::kFloat64);
  EXPECT_LT((norm.mean() - all.mean(0)).abs().max().item<double>(), 1e-9);
  EXPECT_LT((norm.std() - all.std(0, /*unbiased=*/false)).abs().max().item<double>(), 1e-9);
  auto y = norm.normalize(x2);
  EXPECT_EQ(y.scalar_type(), torch::kFloat32);
  EXPECT_LT((norm.inverse(y) - x2).abs().max().item<double>(), 1e-5);
  EXPECT_THROW(norm.accumulate(torch::zeros({4, 2})), InputError);
  Normalizer constant(2);
  constant.accumulate(torch::ones({5, 2}));
  EXPECT_TRUE(torch::isfinite(constant.normalize(torch::ones({1, 2}))).all().item<bool>());
}

TEST(Networks, RejectsInputsThatDoNotMatchTheGraph) {
  auto p = make_problem(5, 4, 3, false);
  BsmsGnn model(lagrangian_options(3));
  EXPECT_THROW(model.forward(p.nodes.slice(0, 1), p.positions, p.graph), InputError);
  EXPECT_THROW(model.forward(p.nodes, {p.positions[0]}, p.graph), InputError);
  BsmsGnn deeper(lagrangian_options(4));
  EXPECT_THROW(deeper.forward(p.nodes, p.positions, p.graph), InputError);
  auto o = lagrangian_options(3);
  o.edge_set_fields = {{0, 2}};
  EXPECT_THROW(BsmsGnn{o}, InputError);
}

}  // namespace
}  // namespace bsms
