// Hard-case experiments (zero-shot, seeding, long rollouts) on the synthetic plate data, the
// rollout's stability metrics, and the wall inputs of the Lagrangian adapter.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "core/error.hpp"
#include "pipeline/adapters/lagrangian.hpp"
#include "pipeline/adapters/scene_features.hpp"
#include "pipeline/experiments/hard_cases.hpp"
#include "pipeline/rollout/rollout.hpp"
#include "pipeline/runs/rollout_metrics.hpp"
#include "pipeline/train/trainer.hpp"
#include "plate_data.hpp"
#include "scene_text.hpp"

namespace bsms {
namespace {

namespace fs = std::filesystem;
using testing::fresh_dir;
using testing::write_config;
using testing::write_split;

class HardCasesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fresh_dir("hard");
    write_split(dir_ / "data", "train", 4, 12);  // horizon: 10 predicted steps
    write_split(dir_ / "data", "valid", 1, 12);
    write_split(dir_ / "data", "test", 2, 20);
    TrainRequest r;
    r.config_path = write_config(dir_, dir_ / "data", "bsms", 60);
    r.out = (dir_ / "run").string();
    r.threads = 1;
    r.quiet = true;
    train(r);
  }
  void TearDown() override { fs::remove_all(dir_); }

  HardCaseRequest request(const std::string& name) const {
    HardCaseRequest q;
    q.runs = {(dir_ / "run").string()};
    q.out = (dir_ / name).string();
    q.threads = 1;
    q.quiet = true;
    return q;
  }
  fs::path dir_;
};

TEST_F(HardCasesTest, SeedingRatiosAreAgainstTheTrainingSeeding) {
  const Json m = seeding_experiment(request("seeding"));
  ASSERT_EQ(m["runs"].size(), 1u);
  const Json& run = m["runs"][0];
  EXPECT_EQ(run["trained_with"], "minave");
  for (const char* s : {"minave", "closecenter", "random"}) {
    EXPECT_EQ(run["rollouts"][s]["seeding"], s);
    EXPECT_TRUE(std::isfinite(run["ratios"][s]["rmse_all"].get<double>())) << s;
  }
  // Each ratio is the rollout's RMSE over the training seeding's, and random seeding really
  // builds other graphs: its rollout differs (were the seeding ignored, every ratio would be 1).
  const Json& rollouts = run["rollouts"];
  for (const char* s : {"closecenter", "random"}) {
    for (const char* k : {"rmse_1", "rmse_all"}) {
      const double expected = rollouts[s][k]["world_pos"].get<double>() /
                              rollouts["minave"][k]["world_pos"].get<double>();
      EXPECT_NEAR(run["ratios"][s][k].get<double>(), expected, 1e-12) << s << ' ' << k;
    }
  }
  // (CloseCenter may pick MinAve's seeds on this small regular plate; random does not.)
  EXPECT_GT(std::abs(run["ratios"]["random"]["rmse_1"].get<double>() - 1.0), 1e-6);
  EXPECT_TRUE(fs::exists(dir_ / "seeding" / "seeding.md"));
  EXPECT_TRUE(fs::exists(dir_ / "seeding" / "plots" / "seeding_rmse.png"));
}

TEST_F(HardCasesTest, ZeroShotNeedsMeshesFourTimesLarger) {
  write_split(dir_ / "large", "test", 1, 14, 14);  // 225 nodes against 49: 4.6x
  const Json m = zero_shot_experiment(request("zero_shot"), (dir_ / "large").string());
  EXPECT_EQ(m["train_max_nodes"], 49);
  EXPECT_NEAR(m["size_ratio_min"].get<double>(), 225.0 / 49.0, 1e-9);
  const Json& run = m["runs"][0];
  EXPECT_EQ(run["zero_shot"]["num_nodes_mean"].get<double>(), 225.0);
  EXPECT_TRUE(std::isfinite(run["zero_shot"]["rmse_all"]["world_pos"].get<double>()));
  EXPECT_TRUE(fs::exists(dir_ / "zero_shot" / "zero_shot.md"));

  write_split(dir_ / "medium", "test", 1, 14, 8);  // 81 nodes: 1.7x
  try {
    zero_shot_experiment(request("zero_shot2"), (dir_ / "medium").string());
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("81 nodes"), std::string::npos) << e.what();
  }
}

TEST_F(HardCasesTest, LongRolloutReportsErrorAtMultiplesOfTheHorizon) {
  // A floor at y = 0 that the falling plate passes through (the data has no contact).
  const char* floor = R"({"scene": {"dim": 2,
      "background": {"type": "box", "min": [-1, 0], "max": [2, 2], "element_size": 0.1},
      "boundaries": [{"group": "bottom", "type": "fixed"}], "solver": {"end_time": 1.0}}})";
  write_split(dir_ / "long", "test", 1, 102, 6, testing::dragged_plate, floor);  // 10 x 10 steps
  write_split(dir_ / "short", "test", 1, 60);
  const Json m =
      long_rollout_experiment(request("long"), (dir_ / "long").string(), (dir_ / "short").string());
  const Json& run = m["runs"][0];
  EXPECT_EQ(run["horizon_steps"], 10);
  for (const char* k : {"1H", "2H", "5H", "10H"}) EXPECT_TRUE(run["rmse_at"][k].is_number()) << k;
  EXPECT_EQ(run["rollout"]["rmse_per_step"]["world_pos"].size(), 100u);
  EXPECT_EQ(run["rollout"]["inverted_cells_per_step"].size(), 100u);
  // Physical validity beside the inverted cells, of the prediction and of the truth: one body
  // overlaps nothing; the truth falls ~0.3 m below the floor.
  const Json& validity = run["rollout"]["validity"];
  ASSERT_TRUE(validity.is_object()) << run["rollout"].dump();
  EXPECT_EQ(validity["model"]["overlap"]["per_step"].size(), 100u);
  EXPECT_EQ(validity["truth"]["overlap"]["max"].get<double>(), 0.0);
  EXPECT_GT(validity["truth"]["outside_walls"]["max"].get<double>(), 0.2);
  EXPECT_GT(validity["truth"]["nodes_outside_walls"]["max"].get<double>(), 0.5);
  EXPECT_EQ(validity["model"]["outside_walls"]["per_trajectory"].size(), 1u);
  {
    std::ifstream md(dir_ / "long" / "long_rollout.md");
    const std::string text((std::istreambuf_iterator<char>(md)), {});
    EXPECT_NE(text.find("| Overlap between bodies (max, model / truth) | Outside the walls"),
              std::string::npos)
        << text;
    EXPECT_NE(text.find(" / 0.00e+00 |"), std::string::npos) << text;  // the truth's overlap
  }
  EXPECT_EQ(m["hard_runs"].size(), 1u);
  EXPECT_TRUE(fs::exists(dir_ / "long" / "long_rollout.md"));
  EXPECT_TRUE(fs::exists(dir_ / "long" / "plots" / "long_rmse.png"));
  // Trajectories shorter than 10x the horizon are refused.
  EXPECT_THROW(long_rollout_experiment(request("long2"), (dir_ / "short").string(), std::string()),
               InputError);
}

TEST_F(HardCasesTest, ProjectionKeepsEveryPredictedNodeInsideAndEveryCellTheRightWayOut) {
  // The falling plate passes through a floor at y = 0.3 within the trajectory; the truth does too.
  // Its two pinned corners (kinematic: the scene holds them, at y = 0 and 0.6) are not moved.
  const char* floor = R"({"scene": {"dim": 2,
      "background": {"type": "box", "min": [-1, 0.3], "max": [2, 2], "element_size": 0.1},
      "boundaries": [{"group": "bottom", "type": "slip"}], "solver": {"end_time": 1.0}}})";
  write_split(dir_ / "floor", "test", 1, 40, 6, testing::dragged_plate, floor);
  RolloutRequest q;
  q.run = (dir_ / "run").string();
  q.data = (dir_ / "floor").string();
  q.threads = 1;
  q.quiet = true;
  q.out = (dir_ / "plain").string();
  const RolloutMetrics plain = rollout(q);
  ASSERT_TRUE(plain.validity && plain.validity->model.outside_walls);
  EXPECT_GT(plain.validity->truth.outside_walls->max, 0.01);
  EXPECT_GT(plain.validity->model.outside_walls->max, 0.01);
  EXPECT_FALSE(plain.projection);
  q.projection = parse_projection("walls");
  q.out.clear();
  const RolloutMetrics projected = rollout(q);
  ASSERT_TRUE(projected.projection);
  EXPECT_EQ(projected.projection->constraints, std::vector<std::string>{"walls"});
  EXPECT_GT(projected.projection->nodes_clamped_per_step, 0.0);
  EXPECT_GT(projected.projection->shift_rms, 0.0);
  const double one_node = 1.0 / 49;  // the pinned corner 0.3 below the floor
  EXPECT_GT(plain.validity->model.nodes_outside_walls->max, 1.5 * one_node);
  EXPECT_NEAR(projected.validity->model.outside_walls->max, 0.3, 1e-6);
  EXPECT_NEAR(projected.validity->model.nodes_outside_walls->max, one_node, 1e-9);
  // The truth is scored as it is; the default folder says what was done.
  EXPECT_EQ(projected.validity->truth.outside_walls->max, plain.validity->truth.outside_walls->max);
  const fs::path folder = dir_ / "run" / "rollout_walls";
  EXPECT_TRUE(fs::exists(folder / "metrics.json"));
  const RolloutMetrics read = read_rollout_metrics((folder / "metrics.json").string());
  ASSERT_TRUE(read.projection);
  EXPECT_EQ(read.projection->steps, projected.projection->steps);
  // Every constraint: cells turned inside out only where the projection says it could not hold
  // them (a cell of the pinned corner below the floor can be left no room).
  q.projection = parse_projection("all");
  const RolloutMetrics all = rollout(q);
  EXPECT_TRUE(all.inverted_cells_max == 0.0 || all.projection->unconverged_steps > 0);
  EXPECT_NEAR(all.validity->model.nodes_outside_walls->max, one_node, 1e-9);
  EXPECT_TRUE(fs::exists(dir_ / "run" / "rollout_walls+cells+contact" / "metrics.json"));
  // A scene without walls has nothing to project onto.
  q.data = (dir_ / "data").string();
  q.projection = parse_projection("walls");
  EXPECT_THROW(rollout(q), InputError);
}

TEST(Walls, ResolvedFromTheBoxAndItsNamedSides) {
  LagrangianSpec s;
  s.dim = 2;
  resolve_walls(s, testing::typed_scene(R"({"scene": {"dim": 2,
                    "background": {"type": "box", "min": [0, -1], "max": [2, 1],
                                   "element_size": 0.1},
                    "boundaries": [{"group": "left", "type": "fixed"},
                                   {"group": "top", "type": "fixed"}],
                    "solver": {"end_time": 1.0}}})"),
                0.1);
  ASSERT_TRUE(s.has_walls());
  EXPECT_EQ(s.wall_lo[0], 0.0);
  EXPECT_TRUE(std::isnan(s.wall_hi[0]));
  EXPECT_TRUE(std::isnan(s.wall_lo[1]));
  EXPECT_EQ(s.wall_hi[1], 1.0);
  EXPECT_EQ(s.input_size(), 2 + 4 + 4);
  // Round trip through the run's features_resolved.
  const LagrangianSpec back = lagrangian_spec_from_json(to_json(s), "test");
  EXPECT_EQ(back.wall_lo[0], 0.0);
  EXPECT_TRUE(std::isnan(back.wall_hi[0]));
  EXPECT_EQ(back.wall_radius, 0.1);

  // Inputs: clipped distance / radius per side; 1 where there is no wall.
  TrajectoryMesh mesh = testing::dragged_plate(0, 2).mesh;
  MeshGraphs graphs;
  const int64_t n = mesh.num_nodes();
  auto x = torch::zeros({n, 2});
  x.index_put_({0, 0}, 0.05);  // 0.05 from the left wall: 0.5
  x.index_put_({0, 1}, 0.97);  // 0.03 below the top: 0.3
  LagrangianAdapter adapter(s);
  FrameState state{&graphs, &mesh, x, x, {}, {}};
  graphs.hierarchy = MultilevelTensors();
  const auto inputs = adapter.make_batch({state}).inputs;
  ASSERT_EQ(inputs.size(1), 10);
  EXPECT_NEAR(inputs[0][6].item<float>(), 0.5f, 1e-5);
  EXPECT_EQ(inputs[0][7].item<float>(), 1.0f);
  EXPECT_EQ(inputs[0][8].item<float>(), 1.0f);
  EXPECT_NEAR(inputs[0][9].item<float>(), 0.3f, 1e-5);

  // Moved to a larger box (zero-shot), and to a scene without walls: same input size.
  const LagrangianSpec big = walls_for_scene(s, testing::typed_scene(R"({"scene": {"dim": 2,
      "background": {"type": "box", "min": [0, 0], "max": [3, 3], "element_size": 0.1},
      "boundaries": [{"group": "right", "type": "fixed"}], "solver": {"end_time": 1.0}}})"));
  EXPECT_TRUE(std::isnan(big.wall_lo[0]));
  EXPECT_EQ(big.wall_hi[0], 3.0);
  EXPECT_EQ(big.wall_radius, 0.1);
  EXPECT_EQ(big.input_size(), s.input_size());
  const LagrangianSpec open = walls_for_scene(s, testing::typed_scene("{}"));
  EXPECT_TRUE(open.has_walls());
  EXPECT_TRUE(std::isnan(open.wall_lo[1]) && std::isnan(open.wall_hi[1]));
  EXPECT_EQ(open.input_size(), s.input_size());
  // The momentum projection along slip walls moves only to scenes whose walls all slip.
  LagrangianSpec slipping = s;
  slipping.momentum_radius = 0.12;
  slipping.momentum_wall_range = 0.08;
  slipping.momentum_slip_walls = true;
  auto moved = [&](const std::string& type) {
    return walls_for_scene(slipping, testing::typed_scene(R"({"scene": {"dim": 2,
        "background": {"type": "box", "min": [0, 0], "max": [3, 3], "element_size": 0.1},
        "solver": {"end_time": 1.0}, "boundaries": [{"group": "right", "type": ")" +
                                                          type + R"("}]}})"));
  };
  EXPECT_TRUE(moved("slip").momentum_slip_walls);
  EXPECT_TRUE(moved("roller").momentum_slip_walls);
  EXPECT_FALSE(moved("fixed").momentum_slip_walls);
  EXPECT_DOUBLE_EQ(moved("fixed").momentum_radius, 0.12);  // free groups still conserve

  // No box, or a box without named sides: no walls.
  for (const char* scene : {R"({"scene": {"dim": 2, "background": {"type": "mesh", "path": "m.msh"},
            "solver": {"end_time": 1.0}}})",
                            R"({"scene": {"dim": 2,
            "background": {"type": "box", "min": [0, 0], "max": [1, 1], "element_size": 0.1},
            "boundaries": [], "solver": {"end_time": 1.0}}})",
                            "{}"}) {
    LagrangianSpec t;
    resolve_walls(t, testing::typed_scene(scene), 0.1);
    EXPECT_FALSE(t.has_walls()) << scene;
    EXPECT_EQ(t.input_size(), 2 + 4);
  }
}

}  // namespace
}  // namespace bsms
