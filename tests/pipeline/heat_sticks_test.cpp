// The heat-sticks experiment (thesis Fig. 4.6): the isolation property that makes bi-stride pooling
// safe across a gap, checked without training, and a short end-to-end run.
#include "pipeline/experiments/heat_sticks.hpp"

#include <gtest/gtest.h>
#include <torch/torch.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/error.hpp"
#include "tests/temp_dir.hpp"

namespace bsms {
namespace {

namespace fs = std::filesystem;

constexpr int64_t kNodes = 33;
constexpr int kLevels = 5;

// Two sticks with a gap of 0.25 dx: A on [0, 1], B on [1 + gap, 2 + gap].
struct PairSetup {
  Sticks pair, a, b;
  std::vector<StickBc> bcs;
};

PairSetup pair_setup() {
  const double dx = 1.0 / (kNodes - 1), start = 1.0 + 0.25 * dx;
  PairSetup s{make_sticks({0.0, start}, kNodes),
              make_sticks({0.0}, kNodes),
              make_sticks({start}, kNodes),
              {}};
  StickBc a, b;
  a.dirichlet_left = true;  // A's flux end faces B's Dirichlet end
  a.t_dirichlet = -0.8;
  a.flux = 0.9;
  b.dirichlet_left = true;
  b.t_dirichlet = 0.7;
  b.flux = -0.6;
  s.bcs = {a, b};
  return s;
}

torch::Tensor predict(BsmsGnn& model, const Sticks& sticks, const std::vector<StickBc>& bcs,
                      const MultilevelTensors& graph) {
  torch::NoGradGuard no_grad;
  return model.forward(stick_inputs(sticks, bcs), {sticks.positions}, graph);
}

TEST(HeatSticks, InputsAndExactSolution) {
  const Sticks s = make_sticks({0.0, 2.0}, 5);
  ASSERT_EQ(s.num_sticks(), 2);
  EXPECT_DOUBLE_EQ(s.dx(), 0.25);
  EXPECT_EQ(s.edges.size(0), 2 * 2 * 4);
  StickBc left{true, 0.5, -1.0}, right{false, -0.25, 0.5};
  auto in = stick_inputs(s, {left, right});
  auto t = stick_solution(s, {left, right});
  // Stick 0: Dirichlet at node 0, flux at node 4; stick 1 mirrored.
  EXPECT_TRUE(torch::equal(in[0], torch::tensor({1.0f, 0.0f, 0.5f})));
  EXPECT_TRUE(torch::equal(in[4], torch::tensor({0.0f, 1.0f, -1.0f})));
  EXPECT_TRUE(torch::equal(in[5], torch::tensor({0.0f, 1.0f, 0.5f})));
  EXPECT_TRUE(torch::equal(in[9], torch::tensor({1.0f, 0.0f, -0.25f})));
  EXPECT_EQ(in.slice(0, 1, 4).abs().sum().item<float>(), 0.0f);
  // T = T_d + q s, s = distance from the Dirichlet end.
  EXPECT_NEAR(t[0][0].item<float>(), 0.5f, 1e-6);
  EXPECT_NEAR(t[2][0].item<float>(), 0.0f, 1e-6);
  EXPECT_NEAR(t[4][0].item<float>(), -0.5f, 1e-6);
  EXPECT_NEAR(t[9][0].item<float>(), -0.25f, 1e-6);
  EXPECT_NEAR(t[5][0].item<float>(), 0.25f, 1e-6);
  EXPECT_THROW(stick_inputs(s, {left}), InputError);
}

// The key property: a randomly initialised network on the bi-stride hierarchy of the two sticks
// predicts exactly what it predicts for each stick alone; on the proximity hierarchy it does not.
TEST(HeatSticks, BiStrideKeepsTheSticksIsolatedProximityDoesNot) {
  const PairSetup s = pair_setup();
  torch::manual_seed(11);
  BsmsGnn model(heat_model_options(kLevels, 32));
  model.eval();

  auto bs_pair = predict(model, s.pair, s.bcs, bistride_multilevel(s.pair, kLevels));
  auto bs_alone = torch::cat({predict(model, s.a, {s.bcs[0]}, bistride_multilevel(s.a, kLevels)),
                              predict(model, s.b, {s.bcs[1]}, bistride_multilevel(s.b, kLevels))});
  EXPECT_LE((bs_pair - bs_alone).abs().max().item<double>(), 1e-5);

  auto px_pair = predict(model, s.pair, s.bcs, proximity_multilevel(s.pair, kLevels));
  auto px_alone = torch::cat({predict(model, s.a, {s.bcs[0]}, proximity_multilevel(s.a, kLevels)),
                              predict(model, s.b, {s.bcs[1]}, proximity_multilevel(s.b, kLevels))});
  // The nodes next to the gap: A's last three and B's first three.
  auto near = torch::arange(kNodes - 3, kNodes + 3);
  const double scale = px_alone.abs().max().item<double>();
  const double diff = (px_pair - px_alone).index_select(0, near).abs().max().item<double>();
  EXPECT_GT(diff, 0.01 * scale) << "difference " << diff << ", output scale " << scale;
}

TEST(HeatSticks, OnlyProximityHasEdgesAcrossTheGap) {
  const PairSetup s = pair_setup();
  const auto bs = stick_mixing(bistride_multilevel(s.pair, kLevels), s.pair.stick);
  const auto px = stick_mixing(proximity_multilevel(s.pair, kLevels), s.pair.stick);
  ASSERT_EQ(bs.cross_stick_edges.size(), static_cast<size_t>(kLevels));
  ASSERT_EQ(px.cross_stick_edges.size(), static_cast<size_t>(kLevels));
  for (int k = 0; k < kLevels; ++k) {
    EXPECT_EQ(bs.cross_stick_edges[k], 0) << "level " << k;
    EXPECT_EQ(bs.mixed_nodes[k], 0) << "level " << k;
  }
  EXPECT_EQ(px.cross_stick_edges[0], 0);  // level 0 is the mesh
  for (int k = 1; k < kLevels; ++k) EXPECT_GT(px.cross_stick_edges[k], 0) << "level " << k;
  // With a gap of 0.25 dx, A's last node shares a level-1 cell with B's first nodes.
  EXPECT_GT(px.mixed_nodes[1], 0);
}

TEST(HeatSticks, ProximityEdgeWithoutSharedCell) {
  // A gap of 2.5 dx puts A's last node (alone in its level-1 cell of 2 dx) and B's first node in
  // neighbouring cells: no shared cell at level 1, but an edge across the gap.
  const double dx = 1.0 / (kNodes - 1);
  const Sticks pair = make_sticks({0.0, 1.0 + 2.5 * dx}, kNodes);
  const auto px = stick_mixing(proximity_multilevel(pair, 3), pair.stick);
  EXPECT_EQ(px.mixed_nodes[1], 0);
  EXPECT_GT(px.cross_stick_edges[1], 0);
}

TEST(HeatSticks, ValidatesOptions) {
  HeatSticksOptions o;
  o.out = "unused";
  EXPECT_NO_THROW(validate(o));
  EXPECT_EQ(max_stick_levels(33), 5);
  auto message = [](HeatSticksOptions bad) {
    try {
      validate(bad);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  auto with = [&](auto change) {
    HeatSticksOptions bad = o;
    change(bad);
    return message(bad);
  };
  EXPECT_NE(with([](auto& b) { b.nodes = 4; }).find("--nodes"), std::string::npos);
  EXPECT_NE(with([](auto& b) { b.levels = 1; }).find("--levels"), std::string::npos);
  EXPECT_NE(with([](auto& b) { b.levels = 6; }).find("at most 5"), std::string::npos);
  EXPECT_NE(with([](auto& b) { b.gap = 0.0; }).find("--gap"), std::string::npos);
  EXPECT_NE(with([](auto& b) { b.gap = -1.0; }).find("--gap"), std::string::npos);
  EXPECT_NE(with([](auto& b) { b.steps = 0; }).find("--steps"), std::string::npos);
  EXPECT_NE(with([](auto& b) { b.latent = 0; }).find("--latent"), std::string::npos);
  EXPECT_NE(with([](auto& b) { b.out.clear(); }).find("--out"), std::string::npos);
}

TEST(HeatSticks, ShortRunWritesMetricsAndPlot) {
  const fs::path dir = testing::unique_temp_dir("heat_sticks") / "run";
  HeatSticksOptions o;
  o.out = dir.string();
  o.steps = 15;
  o.nodes = 17;
  o.levels = 3;
  o.latent = 8;
  o.batch = 2;
  o.test_draws = 2;
  o.threads = 1;
  const Json m = run_heat_sticks(o);
  ASSERT_TRUE(fs::exists(dir / "metrics.json"));
  const Json stored = load_json_file((dir / "metrics.json").string());
  EXPECT_EQ(stored, m);
  for (const char* key : {"bistride", "proximity"}) {
    const Json& r = stored["models"][key];
    for (const char* field : {"train_loss_final", "rmse_alone", "rmse_pair", "rmse_pair_near_gap",
                              "rmse_alone_near_gap", "train_wall_s", "max_abs_pair_minus_alone"}) {
      ASSERT_TRUE(r[field].is_number()) << key << "." << field;
      EXPECT_TRUE(std::isfinite(r[field].get<double>())) << key << "." << field;
    }
    EXPECT_EQ(r["train_steps"].get<int64_t>(), 15);
    EXPECT_EQ(r["rmse_pair_by_combo"].size(), 4u);
    EXPECT_EQ(r["test_hierarchy"]["cross_gap_edges_per_level"].size(), 3u);
  }
  for (auto n : stored["models"]["bistride"]["test_hierarchy"]["cross_gap_edges_per_level"]) {
    EXPECT_EQ(n.get<int64_t>(), 0);
  }
  EXPECT_LE(stored["models"]["bistride"]["max_abs_pair_minus_alone"].get<double>(), 1e-5);
  EXPECT_TRUE(fs::exists(dir / "profiles.csv"));
  EXPECT_TRUE(fs::exists(dir / "train_log.csv"));
  EXPECT_TRUE(fs::exists(dir / "heat_sticks.md"));
  // 4 combinations x 2 draws x 2 sticks x 17 nodes, plus the header.
  std::ifstream csv(dir / "profiles.csv");
  int64_t lines = 0;
  for (std::string line; std::getline(csv, line);) ++lines;
  EXPECT_EQ(lines, 1 + 4 * 2 * 2 * 17);
  if (std::system("command -v gnuplot >/dev/null 2>&1") == 0) {
    EXPECT_TRUE(fs::exists(dir / "plots" / "heat_sticks.png"));
    EXPECT_GT(fs::file_size(dir / "plots" / "heat_sticks.png"), 1000u);
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace bsms
