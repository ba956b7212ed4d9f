// End-to-end training and rollout on a small synthetic Lagrangian dataset: a triangulated plate
// moving under gravity and drag with a per-trajectory initial velocity and two pinned nodes.
#include <ATen/CPUGeneratorImpl.h>
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "data/dataset/dataset.hpp"
#include "gif_frames.hpp"
#include "models/checkpoint.hpp"
#include "models/fused_adam.hpp"
#include "pipeline/adapters/scene_symmetry.hpp"
#include "pipeline/adapters/simulator.hpp"
#include "pipeline/report/animation.hpp"
#include "pipeline/report/plotting.hpp"
#include "pipeline/report/report.hpp"
#include "pipeline/rollout/rollout.hpp"
#include "pipeline/runs/run_files.hpp"
#include "pipeline/runs/train_stats.hpp"
#include "pipeline/train/legacy_checkpoint.hpp"
#include "pipeline/train/trainer.hpp"
#include "pipeline/train/training_data.hpp"
#include "plate_data.hpp"
#include "scene_text.hpp"

namespace bsms {
namespace {

namespace fs = std::filesystem;
using testing::fresh_dir;
using testing::write_config;
using testing::write_split;

class PipelineTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // ctest runs each test in its own process, possibly at the same time: one folder each.
    dir_ = fresh_dir("suite");
    fs::create_directories(dir_ / "data");
    write_split(dir_ / "data", "train", 6, 12);
    write_split(dir_ / "data", "valid", 2, 12);
    write_split(dir_ / "data", "test", 2, 30);
  }
  static fs::path dir_;
};
fs::path PipelineTest::dir_;

double first_logged_loss(const std::string& run) {
  std::ifstream in(run_log_path(run));
  std::string header, line;
  std::getline(in, header);
  std::getline(in, line);
  const auto a = line.find(','), b = line.find(',', a + 1), c = line.find(',', b + 1);
  return std::stod(line.substr(b + 1, c - b - 1));
}

TEST_F(PipelineTest, BsmsLearnsTheFallingPlateAndRollsOut) {
  TrainRequest r;
  r.config_path = write_config(dir_, dir_ / "data", "bsms", 600);
  r.out = (dir_ / "run_bsms").string();
  r.threads = 2;
  r.quiet = true;
  const TrainResult result = train(r);
  EXPECT_EQ(result.steps, 600);
  EXPECT_LT(result.final_loss, 0.05 * first_logged_loss(r.out));
  EXPECT_TRUE(fs::exists(run_checkpoint_path(r.out)));

  RolloutRequest q;
  q.run = r.out;
  q.quiet = true;
  const RolloutMetrics metrics = rollout(q);
  // What rollout returns is what its metrics file holds, read back by the strict reader.
  const RolloutMetrics saved =
      read_rollout_metrics((fs::path(r.out) / "rollout" / "metrics.json").string());
  EXPECT_EQ(to_json(saved).dump(), to_json(metrics).dump());
  EXPECT_EQ(metrics.model, "bsms");
  EXPECT_FALSE(metrics.eulerian);
  EXPECT_EQ(metrics.num_nodes_mean, 49.0);
  EXPECT_GE(metrics.threads, 1);
  EXPECT_GT(metrics.infer_ms_per_step, 0.0);
  EXPECT_GT(metrics.peak_rss_mb_infer, 0.0);
  ASSERT_TRUE(metrics.train_ms_per_step && metrics.peak_rss_mb_train && metrics.train_steps);
  EXPECT_EQ(*metrics.train_steps, 600);
  ASSERT_TRUE(metrics.rmse_1 && metrics.rmse_50 && metrics.rmse_all);
  const double rmse_all = metrics.rmse_all->at("world_pos");
  EXPECT_TRUE(std::isfinite(rmse_all));
  // 28 predicted steps in which the plate travels ~0.3 m: far better than standing still.
  EXPECT_LT(rmse_all, 0.02);
  EXPECT_LE(metrics.rmse_1->at("world_pos"), rmse_all + 1e-12);
  // The learned gravity and drag beat extrapolating the first velocity, and no cell turns over.
  ASSERT_TRUE(metrics.rmse_all_constant_velocity);
  EXPECT_LT(rmse_all, 0.5 * *metrics.rmse_all_constant_velocity);
  // RMSE-all split by body: the squares of centre, rotation and deformation add up to its square,
  // for the model and for the constant-velocity reference.
  ASSERT_TRUE(metrics.rmse_all_parts && metrics.rmse_all_parts_constant_velocity);
  const auto squares = [](const MotionRmse& p) {
    return p.centre * p.centre + p.rotation * p.rotation + p.deformation * p.deformation;
  };
  EXPECT_NEAR(squares(*metrics.rmse_all_parts), rmse_all * rmse_all, 1e-5 * rmse_all * rmse_all);
  const double cv = *metrics.rmse_all_constant_velocity;
  EXPECT_NEAR(squares(*metrics.rmse_all_parts_constant_velocity), cv * cv, 1e-5 * cv * cv);
  // Per trajectory: the step-weighted RMS of the trajectories' RMSEs is RMSE-all (model and
  // reference), and the bootstrap interval of the ratio holds the ratio.
  ASSERT_TRUE(metrics.per_trajectory);
  const TrajectoryRmse& per = *metrics.per_trajectory;
  ASSERT_EQ(static_cast<int64_t>(per.size()), metrics.num_trajectories);
  double model_sq = 0, cv_sq = 0, steps = 0;
  for (size_t t = 0; t < per.size(); ++t) {
    EXPECT_EQ(per.steps[t], 28);
    model_sq += static_cast<double>(per.steps[t]) * per.model[t] * per.model[t];
    cv_sq +=
        static_cast<double>(per.steps[t]) * per.constant_velocity[t] * per.constant_velocity[t];
    steps += static_cast<double>(per.steps[t]);
  }
  EXPECT_NEAR(std::sqrt(model_sq / steps), rmse_all, 1e-6 * rmse_all);
  EXPECT_NEAR(std::sqrt(cv_sq / steps), cv, 1e-6 * cv);
  if (per.size() >= 2) {
    ASSERT_TRUE(metrics.rmse_all_ratio_interval);
    EXPECT_LE(metrics.rmse_all_ratio_interval->lo, rmse_all / cv + 1e-12);
    EXPECT_GE(metrics.rmse_all_ratio_interval->hi, rmse_all / cv - 1e-12);
  }
  // The plate falls and drags without turning much: its shape hardly changes, far less than it
  // moves.
  ASSERT_TRUE(metrics.rmse_all_deformation_rigid);
  EXPECT_GE(*metrics.rmse_all_deformation_rigid, 0.0);
  EXPECT_LT(*metrics.rmse_all_deformation_rigid, 0.1 * cv);
  EXPECT_EQ(metrics.inverted_cells_max, 0.0);
  EXPECT_EQ(metrics.inverted_cells_per_step.size(), 28u);
  // Physical validity: one body in a scene without walls overlaps nothing, predicted or true,
  // and has no wall measures.
  ASSERT_TRUE(metrics.validity && metrics.validity->model.overlap &&
              metrics.validity->truth.overlap);
  EXPECT_EQ(metrics.validity->model.overlap->max, 0.0);
  EXPECT_EQ(metrics.validity->truth.nodes_in_other_body->max, 0.0);
  EXPECT_EQ(metrics.validity->model.overlap->per_step.size(), 28u);
  EXPECT_EQ(metrics.validity->model.overlap->per_trajectory.size(), 2u);
  EXPECT_FALSE(metrics.validity->model.outside_walls || metrics.validity->truth.outside_walls);
  EXPECT_EQ(metrics.per_step("world_pos").size(), 28u);
  EXPECT_EQ(metrics.seeding, "minave");
  ASSERT_TRUE(metrics.solver_ms_per_frame && metrics.speedup_vs_solver);
  EXPECT_NEAR(*metrics.solver_ms_per_frame, 1000.0 * 0.5 / 29.0, 1e-9);
  EXPECT_TRUE(fs::exists(fs::path(r.out) / "rollout" / "test.h5"));
  EXPECT_TRUE(fs::exists(fs::path(r.out) / "rollout" / "test_000001.xdmf"));
  const Dataset predicted((fs::path(r.out) / "rollout" / "test.h5").string());
  EXPECT_EQ(predicted.num_trajectories(), 2);
  EXPECT_EQ(predicted.num_frames(0), 30);
  // Pinned nodes follow their prescribed (here fixed) positions exactly.
  const auto last = predicted.read(0, "world_pos", 29);
  const auto truth = predicted.read(0, "target_world_pos", 29);
  EXPECT_EQ(last[0], truth[0]);
  EXPECT_EQ(last[1], truth[1]);

  // The report carries the split beside RMSE-all, with the constant-velocity reference's.
  ReportRequest report;
  report.runs = {r.out};
  report.out = (fs::path(r.out) / "report").string();
  std::ifstream md(write_report(report));
  const std::string text((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("| run | RMSE-all | centre | rotation | deformation |"), std::string::npos);
  EXPECT_NE(text.find("| constant velocity ("), std::string::npos) << text;
  EXPECT_NE(text.find("| rigid bodies (each body's first shape held) |"), std::string::npos);
  EXPECT_NE(text.find("| run | RMSE-all / constant velocity | 95 % interval |"), std::string::npos)
      << text;
  EXPECT_NE(text.find("| run | inverted cells (max) | overlap between bodies |"), std::string::npos)
      << text;
  EXPECT_NE(text.find(" | 0.00e+00 / 0.00e+00 | 0.00e+00 / 0.00e+00 | – | – |"), std::string::npos)
      << text;
  // An animation of every frame beside the still frames, each frame titled with its error.
  if (gnuplot_available()) {
    EXPECT_NE(text.find("](plots/rollout_0.png)"), std::string::npos) << text;
    EXPECT_NE(text.find("](plots/rollout_0_animation.gif)"), std::string::npos) << text;
    EXPECT_NE(text.find("](plots/validity_over_steps.png)"), std::string::npos) << text;
    const fs::path plots = fs::path(report.out) / "plots";
    std::ifstream gif(plots / "rollout_0_animation.gif", std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(gif)),
                            std::istreambuf_iterator<char>());
    EXPECT_EQ(testing::gif_frames(bytes), 30);
    std::ifstream gp(plots / "rollout_0_animation.gp");
    const std::string script((std::istreambuf_iterator<char>(gp)),
                             std::istreambuf_iterator<char>());
    const size_t at = script.rfind(',', script.find("]\n", script.find("array err[30] = [")));
    ASSERT_NE(at, std::string::npos) << script;
    EXPECT_NEAR(std::stod(script.substr(at + 1)), rms_distance(last, truth, 2), 1e-6) << script;
  }
  // The same run twice: paired against itself, the ratio and its interval are exactly 1.
  report.runs = {r.out, r.out};
  std::ifstream twice(write_report(report));
  const std::string paired((std::istreambuf_iterator<char>(twice)),
                           std::istreambuf_iterator<char>());
  EXPECT_NE(paired.find("| 1.000 | 1.000–1.000 |"), std::string::npos) << paired;
  // The training-cost table needs two runs: the run reaches its own final validation loss at
  // its end or before it.
  EXPECT_EQ(text.find("| run | final / zero | wall time (s) |"), std::string::npos);
  EXPECT_NE(paired.find("| run | final / zero | wall time (s) | reaches "), std::string::npos)
      << paired;
  EXPECT_NE(paired.find("×) | – |"), std::string::npos) << paired;
  report.runs = {r.out};

  // Teacher forcing (--one-step): every step from the true frames. Its first step is the
  // rollout's; later ones do not carry the drift, and the references step from the truth too
  // (the first step of both references is the rollout's).
  q.one_step = true;
  const RolloutMetrics one = rollout(q);
  EXPECT_TRUE(one.one_step);
  EXPECT_FALSE(metrics.one_step);
  const fs::path one_dir = fs::path(r.out) / "rollout_one_step";
  EXPECT_TRUE(read_rollout_metrics((one_dir / "metrics.json").string()).one_step);
  ASSERT_EQ(one.per_step("world_pos").size(), 28u);
  EXPECT_DOUBLE_EQ(one.per_step("world_pos")[0], metrics.per_step("world_pos")[0]);
  EXPECT_LT(one.rmse_all->at("world_pos"), rmse_all);
  ASSERT_TRUE(one.rmse_all_constant_velocity);
  EXPECT_LT(*one.rmse_all_constant_velocity, cv);
  // Without the drift the last step's error stays far below the rollout's.
  EXPECT_LT(one.per_step("world_pos")[27], 0.5 * metrics.per_step("world_pos")[27]);
  // A report of a run whose rollout folder holds one-step errors is refused with the file named.
  q.out = (fs::path(r.out) / "rollout").string();
  rollout(q);
  try {
    write_report(report);
    ADD_FAILURE() << "a one-step metrics file made a report";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("one-step"), std::string::npos) << e.what();
  }
}

// On a case whose answer is known (springs along mesh edges), a
// correct pipeline learns the one-step acceleration almost exactly, on trajectories it did not
// train on, and the log carries the zero-prediction reference beside the validation loss.
TEST(KnownAnswer, BsmsLearnsSpringPlateAccelerations) {
  const fs::path dir = fresh_dir("springs");
  fs::create_directories(dir / "data");
  write_split(dir / "data", "train", 4, 24, 6, testing::spring_plate);
  write_split(dir / "data", "valid", 2, 24, 6, testing::spring_plate);
  const std::string config = (dir / "springs.json").string();
  std::ofstream(config) << R"({"data": ")" << (dir / "data").string() << R"(", "steps": 1500,
    "valid_every": 500, "valid_samples": 32, "normalizer_steps": 50,
    "model": {"type": "bsms", "latent": 32, "levels": 2},
    "features": {"noise_std": 0.0},
    "optimizer": {"lr": 3e-3, "lr_final": 3e-4, "warmup_steps": 20, "batch_size": 2}})";
  TrainRequest r;
  r.config_path = config;
  r.out = (dir / "run").string();
  r.threads = 2;
  r.quiet = true;
  const TrainResult result = train(r);
  const TrainStats stats = read_train_stats(run_stats_path(r.out));
  const double baseline = stats.final_valid_zero_prediction;
  EXPECT_GT(baseline, 0.5);  // normalised targets: predicting zero scores about dim = 2
  EXPECT_LT(result.final_valid_loss, 0.05 * baseline)
      << "validation loss " << result.final_valid_loss << ", zero prediction " << baseline;
  const Json run = load_json_file(run_config_path(r.out));
  EXPECT_GT(run["features_resolved"]["strain_scale"].get<double>(), 0.01);
  std::ifstream log(run_log_path(r.out));
  std::string header;
  std::getline(log, header);
  EXPECT_EQ(header, "step,wall_s,loss,valid_loss,valid_zero_prediction,lr");
}

// bsms rollout --ensemble: the members' predicted accelerations are averaged at every step, each
// member seeing the state through its own features and graphs.
TEST_F(PipelineTest, EnsembleRolloutAveragesTheMembersAccelerations) {
  std::vector<std::string> runs;
  for (const char* model : {"bsms", "mgn"}) {
    TrainRequest r;
    r.config_path = write_config(dir_, dir_ / "data", model, 30);
    r.out = (dir_ / (std::string("ensemble_") + model)).string();
    r.threads = 1;
    r.quiet = true;
    fs::remove_all(r.out);
    train(r);
    runs.push_back(r.out);
  }
  auto frames = [](const fs::path& dir, int64_t frame) {
    const Dataset d((dir / "test.h5").string());
    return d.read(0, "world_pos", frame, 1);
  };
  RolloutRequest q;
  q.run = runs[0];
  q.max_trajectories = 1;
  q.max_steps = 4;
  q.threads = 1;
  q.quiet = true;
  rollout(q);
  const fs::path plain = fs::path(runs[0]) / "rollout";
  // With itself: (a + a) / 2 is a, so the rollout is the plain one, bit for bit.
  q.ensemble = {runs[0]};
  const RolloutMetrics self = rollout(q);
  const fs::path ensemble = fs::path(runs[0]) / "rollout_ensemble";
  EXPECT_EQ(self.model, "bsms+bsms");
  for (int64_t f = 2; f < 6; ++f) EXPECT_EQ(frames(ensemble, f), frames(plain, f)) << f;
  // With the MGN run: the first predicted frame is the mean of the two runs' own.
  q.ensemble = {runs[1]};
  const RolloutMetrics both = rollout(q);
  EXPECT_EQ(both.model, "bsms+mgn");
  RolloutRequest other = q;
  other.run = runs[1];
  other.ensemble.clear();
  rollout(other);
  const auto a = frames(plain, 2), b = frames(fs::path(runs[1]) / "rollout", 2),
             mean = frames(ensemble, 2);
  ASSERT_EQ(a.size(), mean.size());
  double apart = 0.0;
  for (size_t k = 0; k < a.size(); ++k) {
    EXPECT_NEAR(mean[k], 0.5 * (a[k] + b[k]), 1e-6) << k;
    apart = std::max(apart, static_cast<double>(std::abs(a[k] - b[k])));
  }
  EXPECT_GT(apart, 1e-5);  // the two runs do predict differently
  // A member that is no run is an InputError naming it.
  q.ensemble = {(dir_ / "no_such_run").string()};
  EXPECT_THROW(rollout(q), InputError);
}

// A square box with four slip walls and no gravity: a scene with the 8 symmetries of the square
// (the group --symmetrize and features.augment read; wall inputs and momentum come from it too).
const char* const kSlipBox =
    R"({"scene": {"dim": 2, "background": {"type": "box", "min": [-0.5, -0.5], "max": [1.5, 1.5], "element_size": 0.1}, "boundaries": [{"group": "left", "type": "slip"}, {"group": "right", "type": "slip"}, {"group": "bottom", "type": "slip"}, {"group": "top", "type": "slip"}], "solver": {"end_time": 1.0}}})";

// A training split of `trajectories` dragged plates in kSlipBox under `data`, and a 2-level
// configuration that trains on it.
TrainConfig slip_box_training(const fs::path& data, int trajectories) {
  fs::create_directories(data);
  write_split(data, "train", trajectories, 12, 6, testing::dragged_plate, kSlipBox);
  TrainConfig config;
  config.data = data.string();
  config.model.levels = 2;
  return config;
}

// The member of `group` that maps the plain batch's positions (t and t-1) onto the augmented
// batch's; group.size() when none does.
size_t mapping_symmetry(const std::vector<BoxSymmetry>& group, const Batch& plain,
                        const Batch& augmented) {
  for (size_t k = 0; k < group.size(); ++k)
    if (torch::allclose(augmented.cur, group[k].points(plain.cur), 0.0, 1e-5) &&
        torch::allclose(augmented.prev, group[k].points(plain.prev), 0.0, 1e-5))
      return k;
  return group.size();
}

TEST_F(PipelineTest, SymmetrizedRolloutIsEquivariantToTheBoxsSymmetries) {
  // The plate in the slip-walled square box.
  const char* box = kSlipBox;
  const fs::path data = dir_ / "box_data";
  fs::create_directories(data);
  write_split(data, "train", 4, 12, 6, testing::dragged_plate, box);
  write_split(data, "valid", 1, 12, 6, testing::dragged_plate, box);
  write_split(data, "test", 1, 12, 6, testing::dragged_plate, box);
  // The test trajectory turned by a quarter (x' = c - (y - c), y' = x): a symmetry of the box.
  const auto group = scene_symmetries(testing::typed_scene(box), 2);
  ASSERT_EQ(group.size(), 8u);
  BoxSymmetry turn;
  for (const auto& g : group)
    if (g.source == std::vector<int>{1, 0} && g.sign == std::vector<int>{-1, 1}) turn = g;
  ASSERT_EQ(turn.dim(), 2);
  const fs::path turned = dir_ / "box_turned";
  fs::create_directories(turned);
  {
    const Dataset d((data / "test.h5").string());
    DatasetWriter w((turned / "test.h5").string(), d.scene(), 2, d.frame_dt());
    Trajectory t;
    t.mesh = turn.mesh(d.mesh(0));
    t.seed = d.seed(0);
    t.num_frames = d.num_frames(0);
    auto x = d.read(0, "world_pos", 0, t.num_frames);
    const auto mapped =
        turn.points(torch::from_blob(x.data(), {static_cast<int64_t>(x.size()) / 2, 2}))
            .contiguous();
    t.fields["world_pos"].assign(mapped.data_ptr<float>(),
                                 mapped.data_ptr<float>() + mapped.numel());
    w.add(t);
    w.commit();
  }
  TrainRequest r;
  r.config_path = write_config(dir_, data, "bsms", 30);
  r.out = (dir_ / "box_bsms").string();
  r.threads = 1;
  r.quiet = true;
  fs::remove_all(r.out);
  train(r);
  // Frame k of a rollout of the original and of the turned data, as [N, 2].
  auto frame = [](const fs::path& out, int64_t k) {
    const Dataset d((out / "test.h5").string());
    auto x = d.read(0, "world_pos", k, 1);
    return torch::from_blob(x.data(), {static_cast<int64_t>(x.size()) / 2, 2}).clone();
  };
  auto largest_gap = [&](const fs::path& a, const fs::path& b) {
    double gap = 0.0;
    for (int64_t k = 2; k < 8; ++k)
      gap = std::max(gap, (turn.points(frame(a, k)) - frame(b, k)).abs().max().item<double>());
    return gap;
  };
  RolloutRequest q;
  q.run = r.out;
  q.max_steps = 6;
  q.threads = 1;
  q.quiet = true;
  for (bool symmetrize : {false, true}) {
    q.symmetrize = symmetrize;
    q.data = data.string();
    q.out = (dir_ / (symmetrize ? "box_sym" : "box_plain")).string();
    const RolloutMetrics m = rollout(q);
    EXPECT_EQ(m.symmetries, symmetrize ? 8 : 1);
    q.data = turned.string();
    q.out = (dir_ / (symmetrize ? "box_sym_turned" : "box_plain_turned")).string();
    rollout(q);
  }
  // The plain model is not equivariant (its inputs have axes); the average over the group is, to
  // float rounding, over six predicted frames.
  const double plain = largest_gap(dir_ / "box_plain", dir_ / "box_plain_turned");
  const double sym = largest_gap(dir_ / "box_sym", dir_ / "box_sym_turned");
  EXPECT_GT(plain, 1e-4);
  EXPECT_LT(sym, 1e-5);
  EXPECT_LT(sym, 0.01 * plain);
  // The default output folder; a scene without a box has nothing to average over.
  q.out.clear();
  q.data = data.string();
  rollout(q);
  EXPECT_TRUE(fs::exists(fs::path(r.out) / "rollout_symmetric" / "metrics.json"));
  // The report reads that folder when asked and says what the figures are; a path is refused.
  ReportRequest report;
  report.runs = {r.out};
  report.out = (dir_ / "box_report").string();
  report.rollout = "rollout_symmetric";
  std::ifstream md(write_report(report));
  const std::string text((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("| box_bsms | bsms, averaged over 8 symmetries |"), std::string::npos)
      << text;
  report.rollout = "../box_sym";
  EXPECT_THROW(write_report(report), InputError);
  q.data = (dir_ / "data").string();
  EXPECT_THROW(rollout(q), InputError);
}

// features.augment "symmetries": each noisy training sample is the stored one mapped by a
// symmetry of the box scene, drawn uniformly: the state and the target map like points and
// vectors, every symmetry of the group turns up, and validation batches (no generators) and
// scenes without a symmetry are left alone or refused.
TEST_F(PipelineTest, AugmentedSamplesAreStoredOnesMappedByTheScenesSymmetries) {
  TrainConfig plain_config = slip_box_training(dir_ / "augment_data", 3);
  plain_config.features.noise_std = 0.0;  // noisy path (generators), no noise: exact maps
  TrainConfig augment_config = plain_config;
  augment_config.features.augment = "symmetries";
  const Dataset train_data = Dataset::open_split(plain_config.data, "train");
  const ResolvedModel plain = resolve_model(plain_config, train_data);
  const ResolvedModel augmented = resolve_model(augment_config, train_data);
  EXPECT_TRUE(plain.augment.empty());
  ASSERT_EQ(augmented.augment.size(), 8u);
  GraphStore store(plain_config.model.seeding, plain.levels, {});
  auto make = [&](const ResolvedModel& r, const TrainConfig& c, const SampleRef& ref, uint64_t seed,
                  bool noisy) {
    std::vector<at::Generator> generators = {at::detail::createCPUGenerator(seed)};
    return make_train_batch(r, c, train_data, store, {ref}, noisy ? &generators : nullptr);
  };
  std::set<size_t> seen;
  for (int i = 0; i < 96; ++i) {
    const SampleRef ref = draw_sample(train_data, 5, i, 0);
    const TrainBatch a = make(plain, plain_config, ref, 100 + i, true);
    const TrainBatch b = make(augmented, augment_config, ref, 100 + i, true);
    const size_t match = mapping_symmetry(augmented.augment, a.batch, b.batch);
    ASSERT_LT(match, augmented.augment.size())
        << "sample " << i << " is no image of the stored one";
    seen.insert(match);
    const BoxSymmetry& g = augmented.augment[match];
    // Accelerations ~5e-4 m/frame² from float32 positions ~1 m: a few ulps (6e-8) of rounding.
    EXPECT_LT((b.target - g.vectors(a.target)).abs().max().item<double>(), 5e-7)
        << "sample " << i << ", target scale " << a.target.abs().max().item<double>();
    EXPECT_TRUE(torch::equal(b.batch.mask, a.batch.mask));
    // The mesh positions the model reads are mapped with the world's.
    EXPECT_TRUE(torch::allclose(b.batch.positions[0] * plain.spec.position_scale,
                                g.points(a.batch.positions[0] * plain.spec.position_scale), 0.0,
                                1e-4))
        << "sample " << i;
    // Validation (no generators) sees the data as stored.
    const TrainBatch v = make(augmented, augment_config, ref, 100 + i, false);
    EXPECT_TRUE(torch::equal(v.batch.cur, make(plain, plain_config, ref, 0, false).batch.cur));
  }
  EXPECT_EQ(seen.size(), 8u) << "96 uniform draws from a group of 8 missed a member";
  // With training noise: the same draw as without augmentation (taken before the symmetry, so a
  // run's noise does not depend on the key), added to the mapped state.
  plain_config.features.noise_std = augment_config.features.noise_std = 1e-3;
  for (int i = 0; i < 8; ++i) {
    const SampleRef ref = draw_sample(train_data, 7, i, 0);
    const TrainBatch a = make(plain, plain_config, ref, 300 + i, true);
    const TrainBatch b = make(augmented, augment_config, ref, 300 + i, true);
    ASSERT_TRUE(a.batch.noise.defined() && b.batch.noise.defined());
    EXPECT_TRUE(torch::equal(a.batch.noise, b.batch.noise)) << "sample " << i;
    bool image = false;
    for (const BoxSymmetry& g : augmented.augment)
      image = image || torch::allclose(b.batch.cur - b.batch.noise,
                                       g.points(a.batch.cur - a.batch.noise), 0.0, 1e-5);
    EXPECT_TRUE(image) << "sample " << i << ": noisy state is not a mapped state plus the noise";
  }
  // No box in the fixture's scene: nothing to augment with, and the key says so.
  TrainConfig boxless = augment_config;
  boxless.data = (dir_ / "data").string();
  try {
    resolve_model(boxless, Dataset::open_split(boxless.data, "train"));
    FAIL() << "a scene without symmetry was augmented";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("features.augment"), std::string::npos) << e.what();
  }
}

// Augmentation with pushforward and two velocities seen: the sample is rolled out in the stored
// frame, then mapped with its truth and older frames. With an equivariant predictor (zero
// acceleration) the augmented sample is the plain one mapped: positions, both velocities in the
// inputs, the rollout's drift (Batch::noise) and the target.
TEST_F(PipelineTest, AugmentationMapsPushedForwardSamplesAndTheirHistory) {
  TrainConfig plain_config = slip_box_training(dir_ / "augment_push_data", 2);
  plain_config.features.noise_std = 0.0;
  plain_config.features.history = 2;
  plain_config.features.pushforward = 2;
  TrainConfig augment_config = plain_config;
  augment_config.features.augment = "symmetries";
  const Dataset train_data = Dataset::open_split(plain_config.data, "train");
  const ResolvedModel plain = resolve_model(plain_config, train_data);
  const ResolvedModel augmented = resolve_model(augment_config, train_data);
  ASSERT_EQ(augmented.augment.size(), 8u);
  const int dim = plain.spec.dim;
  GraphStore store(plain_config.model.seeding, plain.levels, {});
  const Predictor zero = [](const Batch& b) { return torch::zeros_like(b.cur); };
  auto make = [&](const ResolvedModel& r, const TrainConfig& c, const SampleRef& ref,
                  uint64_t seed) {
    std::vector<at::Generator> generators = {at::detail::createCPUGenerator(seed)};
    return make_train_batch(r, c, train_data, store, {ref}, &generators, &zero);
  };
  std::set<size_t> seen;
  int drifted = 0;
  for (int i = 0; i < 48; ++i) {
    SampleRef ref = draw_sample(train_data, 9, i, 0);
    ref.frame = std::max<int64_t>(ref.frame, 4);  // room for two pushed steps and an older frame
    const TrainBatch a = make(plain, plain_config, ref, 500 + i);
    const TrainBatch b = make(augmented, augment_config, ref, 500 + i);
    ASSERT_TRUE(a.batch.noise.defined() && b.batch.noise.defined());
    const size_t match = mapping_symmetry(augmented.augment, a.batch, b.batch);
    ASSERT_LT(match, augmented.augment.size()) << "sample " << i << " is no image of the plain one";
    seen.insert(match);
    const BoxSymmetry& g = augmented.augment[match];
    for (int k = 0; k < 2; ++k)  // x_t - x_{t-1} and x_{t-1} - x_{t-2}
      EXPECT_LT((b.batch.inputs.narrow(1, k * dim, dim) -
                 g.vectors(a.batch.inputs.narrow(1, k * dim, dim)))
                    .abs()
                    .max()
                    .item<double>(),
                1e-6)
          << "sample " << i << ", velocity " << k;
    EXPECT_LT((b.batch.noise - g.vectors(a.batch.noise)).abs().max().item<double>(), 1e-6)
        << "sample " << i << ": the rollout's drift";
    EXPECT_LT((b.target - g.vectors(a.target)).abs().max().item<double>(), 5e-7) << "sample " << i;
    if (a.batch.noise.abs().max().item<double>() > 1e-5) ++drifted;
  }
  EXPECT_GE(seen.size(), 6u);
  // The zero predictor drifts from the dragged plate's truth: the drift is really mapped.
  EXPECT_GT(drifted, 24);
}

TEST_F(PipelineTest, ResumeContinuesExactly) {
  TrainRequest straight;
  straight.config_path = write_config(dir_, dir_ / "data", "mgn", 40);
  straight.out = (dir_ / "run_straight").string();
  straight.threads = 1;
  straight.quiet = true;
  fs::remove_all(straight.out);
  train(straight);

  TrainRequest split = straight;
  split.out = (dir_ / "run_split").string();
  fs::remove_all(split.out);
  split.until = 20;  // as if the first session had been stopped at step 20
  EXPECT_EQ(train(split).steps, 20);
  EXPECT_THROW(train(split), InputError);  // the folder holds a checkpoint: --resume required
  split.until = 0;
  split.resume = true;
  EXPECT_EQ(train(split).steps, 40);
  split.overrides = {"model.latent=32"};
  EXPECT_THROW(train(split), InputError);  // another model on resume
  // A run written before a key existed (here model.mp_per_level) resumes: the missing key takes
  // its default, it is not a change of configuration.
  split.overrides.clear();
  Json saved = load_json_file(run_config_path(split.out));
  ASSERT_EQ(saved["config"]["model"].erase("mp_per_level"), 1u);
  write_json_atomic(run_config_path(split.out), saved);
  EXPECT_EQ(train(split).steps, 40);

  // Same parameters bit for bit.
  const Json cfg = load_json_file(run_config_path(straight.out));
  const LagrangianSpec spec = lagrangian_spec_from_json(cfg["features_resolved"], "config");
  const TrainConfig config = parse_train_config(cfg["config"], "config");
  LearnedSimulator a(LagrangianAdapter(spec).model_shape(), config.model, 1),
      b(LagrangianAdapter(spec).model_shape(), config.model, 1);
  EXPECT_EQ(load_checkpoint(run_checkpoint_path(straight.out), a, nullptr).step, 40);
  EXPECT_EQ(load_checkpoint(run_checkpoint_path(split.out), b, nullptr).step, 40);
  const auto pa = a.named_parameters(), pb = b.named_parameters();
  ASSERT_EQ(pa.size(), pb.size());
  for (const auto& item : pa)
    EXPECT_TRUE(torch::equal(item.value(), *pb.find(item.key()))) << item.key();
  const auto ba = a.named_buffers(), bb = b.named_buffers();
  for (const auto& item : ba)
    EXPECT_TRUE(torch::equal(item.value(), *bb.find(item.key()))) << item.key();
  // The log holds each step once.
  std::ifstream log(run_log_path(split.out));
  int lines = 0;
  for (std::string line; std::getline(log, line);) ++lines;
  EXPECT_EQ(lines, 41);
}

// A run that keeps a moving average of its parameters: a resumed run continues the average
// exactly, and rollouts predict with the average, not with the training weights.
TEST_F(PipelineTest, ParameterAverageResumesExactlyAndIsWhatRolloutsUse) {
  TrainRequest straight;
  straight.config_path = write_config(dir_, dir_ / "data", "mgn", 40);
  straight.overrides = {"optimizer.ema_decay=0.9"};
  straight.out = (dir_ / "run_ema").string();
  straight.threads = 1;
  straight.quiet = true;
  train(straight);
  TrainRequest split = straight;
  split.out = (dir_ / "run_ema_split").string();
  split.until = 20;
  train(split);
  split.until = 0;
  split.resume = true;
  split.overrides = {"optimizer.ema_decay=0.5"};
  EXPECT_THROW(train(split), InputError);  // another average on resume
  split.overrides = straight.overrides;
  EXPECT_EQ(train(split).steps, 40);

  const std::string file = run_checkpoint_path(straight.out);
  const CheckpointContents a = read_checkpoint_contents(file, read_checkpoint_bytes(file));
  const std::string split_file = run_checkpoint_path(split.out);
  const CheckpointContents b =
      read_checkpoint_contents(split_file, read_checkpoint_bytes(split_file));
  EXPECT_EQ(a.ema_decay, 0.9);
  EXPECT_EQ(a.ema_updates, 40);
  EXPECT_EQ(b.ema_updates, 40);
  ASSERT_EQ(a.ema.size(), b.ema.size());
  ASSERT_FALSE(a.ema.empty());
  double moved = 0.0;  // how far the average is from the weights
  for (size_t i = 0; i < a.ema.size(); ++i) {
    EXPECT_EQ(a.ema[i].name, b.ema[i].name);
    EXPECT_TRUE(torch::equal(a.ema[i].value, b.ema[i].value)) << a.ema[i].name;
    for (const auto& t : a.model)
      if (t.name == a.ema[i].name)
        moved = std::max(moved, (t.value - a.ema[i].value).abs().max().item<double>());
  }
  EXPECT_GT(moved, 1e-4);

  // The same run with the average written over the weights (and no average): same rollout.
  const fs::path swapped = dir_ / "run_ema_swapped";
  fs::remove_all(swapped);
  fs::copy(straight.out, swapped, fs::copy_options::recursive);
  CheckpointContents c = a;
  for (const auto& e : c.ema)
    for (auto& t : c.model)
      if (t.name == e.name) t.value = e.value;
  c.ema.clear();
  write_checkpoint_contents(run_checkpoint_path(swapped.string()), c);
  // ... and with the average dropped: the training weights, another rollout.
  const fs::path weights = dir_ / "run_ema_weights";
  fs::remove_all(weights);
  fs::copy(straight.out, weights, fs::copy_options::recursive);
  c = a;
  c.ema.clear();
  write_checkpoint_contents(run_checkpoint_path(weights.string()), c);
  auto rmse_of = [&](const std::string& run) {
    RolloutRequest q;
    q.run = run;
    q.split = "valid";
    q.threads = 1;
    q.quiet = true;
    q.out = run + "_rollout";
    const RolloutMetrics m = rollout(q);
    EXPECT_TRUE(m.rmse_all.has_value());
    return m.rmse_all ? m.rmse_all->at("world_pos") : 0.0;
  };
  const double averaged = rmse_of(straight.out);
  EXPECT_EQ(averaged, rmse_of(swapped.string()));
  EXPECT_NE(averaged, rmse_of(weights.string()));
}

// Expects `run` to throw an InputError whose message names `needle`.
template <typename F>
void expect_input_error(F run, const std::string& needle) {
  try {
    run();
    ADD_FAILURE() << "expected an InputError naming " << needle;
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

// One row of RUN/valid_rollout.csv: step, rmse_all, best flag.
struct ScoredCheckpoint {
  int64_t step = 0;
  double rmse = 0.0;
  bool best = false;
};

std::vector<ScoredCheckpoint> read_valid_rollout_log(const std::string& run) {
  std::ifstream in(run_valid_rollout_log_path(run));
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "step,wall_s,trajectories,rmse_all,constant_velocity,ratio,best");
  std::vector<ScoredCheckpoint> rows;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream fields(line);
    for (std::string cell; std::getline(fields, cell, ',');) cells.push_back(cell);
    EXPECT_EQ(cells.size(), 7u) << line;
    if (cells.size() != 7) continue;
    EXPECT_EQ(cells[2], "2") << line;  // valid_rollout_trajectories
    rows.push_back({std::stoll(cells[0]), std::stod(cells[3]), cells[6] == "1"});
  }
  return rows;
}

// Checkpoint selection by rollout: every scored checkpoint is in the log with the RMSE-all of a
// rollout over the first valid trajectories, which an independent rollout of the kept checkpoint
// reproduces; best.h5 is the lowest-scoring one, bsms rollout takes it by default, and a resumed
// run keeps scoring against the best of the first session.
TEST_F(PipelineTest, CheckpointSelectionKeepsTheBestValidationRollout) {
  TrainRequest r;
  r.config_path = write_config(dir_, dir_ / "data", "mgn", 80);
  r.overrides = {"valid_rollout_every=20", "valid_rollout_trajectories=2"};
  r.out = (dir_ / "run_select").string();
  r.threads = 1;
  r.quiet = true;
  fs::remove_all(r.out);
  r.until = 40;  // two sessions: the second resumes with the first's best
  train(r);
  r.until = 0;
  r.resume = true;
  EXPECT_EQ(train(r).steps, 80);

  const std::vector<ScoredCheckpoint> rows = read_valid_rollout_log(r.out);
  ASSERT_EQ(rows.size(), 4u);
  double lowest = 1e300;
  int64_t lowest_step = 0;
  for (size_t k = 0; k < rows.size(); ++k) {
    EXPECT_EQ(rows[k].step, 20 * static_cast<int64_t>(k + 1));
    EXPECT_TRUE(std::isfinite(rows[k].rmse) && rows[k].rmse > 0);
    // A row is flagged best exactly when it beats every row before it (across the sessions).
    EXPECT_EQ(rows[k].best, rows[k].rmse < lowest) << "step " << rows[k].step;
    if (rows[k].rmse < lowest) {
      lowest = rows[k].rmse;
      lowest_step = rows[k].step;
    }
  }
  const TrainStats stats = read_train_stats(run_stats_path(r.out));
  ASSERT_TRUE(stats.best_step && stats.best_valid_rollout_rmse);
  EXPECT_EQ(*stats.best_step, lowest_step);
  EXPECT_NEAR(*stats.best_valid_rollout_rmse, lowest, 1e-5 * lowest);

  RolloutRequest q;
  q.run = r.out;
  q.split = "valid";
  q.max_trajectories = 2;
  q.threads = 1;
  q.quiet = true;
  q.out = (dir_ / "run_select_best").string();
  const RolloutMetrics best = rollout(q);  // default: the best checkpoint
  EXPECT_EQ(best.checkpoint, "best");
  ASSERT_TRUE(best.checkpoint_step && best.rmse_all);
  EXPECT_EQ(*best.checkpoint_step, lowest_step);
  EXPECT_NEAR(best.rmse_all->at("world_pos"), lowest, 1e-5 * lowest);
  q.checkpoint = "latest";
  q.out = (dir_ / "run_select_latest").string();
  const RolloutMetrics latest = rollout(q);
  EXPECT_EQ(latest.checkpoint, "latest");
  ASSERT_TRUE(latest.checkpoint_step && latest.rmse_all);
  EXPECT_EQ(*latest.checkpoint_step, 80);
  EXPECT_NEAR(latest.rmse_all->at("world_pos"), rows.back().rmse, 1e-5 * rows.back().rmse);
  EXPECT_GE(latest.rmse_all->at("world_pos"), best.rmse_all->at("world_pos") * (1 - 1e-6));

  // A run trained without selection has no best checkpoint to ask for.
  TrainRequest plain = r;
  plain.overrides.clear();
  plain.resume = false;
  plain.out = (dir_ / "run_select_none").string();
  fs::remove_all(plain.out);
  plain.until = 20;
  train(plain);
  q.run = plain.out;
  q.checkpoint = "best";
  q.out = (dir_ / "run_select_none_rollout").string();
  expect_input_error([&] { rollout(q); }, "best.h5");
  q.checkpoint.clear();
  EXPECT_EQ(rollout(q).checkpoint, "latest");
  // The scoring interval must fall on checkpoints.
  plain.overrides = {"valid_rollout_every=30"};
  plain.out = (dir_ / "run_select_bad").string();
  expect_input_error([&] { train(plain); }, "valid_rollout_every");
}

// A run older bsms left (RUN/checkpoints/latest.pt, a LibTorch archive, no latest.h5) is refused
// by train --resume and rollout, and convert_torch_checkpoint turns it, once, into the same
// latest.h5: equal tensors, Adam state and step, and the run resumes from it.
TEST_F(PipelineTest, OlderTorchCheckpointIsRefusedThenConvertedOnce) {
  TrainRequest r;
  r.config_path = write_config(dir_, dir_ / "data", "mgn", 6);
  r.out = (dir_ / "run_legacy").string();
  r.threads = 1;
  r.quiet = true;
  r.until = 3;
  fs::remove_all(r.out);
  train(r);
  const std::string h5 = run_checkpoint_path(r.out), pt = legacy_checkpoint_path(h5);
  const Json cfg = load_json_file(run_config_path(r.out));
  const LagrangianSpec spec = lagrangian_spec_from_json(cfg["features_resolved"], "config");
  const TrainConfig config = parse_train_config(cfg["config"], "config");
  LearnedSimulator sim(LagrangianAdapter(spec).model_shape(), config.model,
                       cfg["levels"].get<int>());
  FusedAdam optimizer(sim.parameters(), torch::optim::AdamOptions(config.optimizer.lr));
  const CheckpointInfo info = load_checkpoint(h5, sim, &optimizer);
  {  // written as older bsms wrote it
    torch::serialize::OutputArchive archive, optimizer_archive;
    sim.save(archive);
    optimizer.save(optimizer_archive);
    archive.write("optimizer", optimizer_archive);
    archive.write("step", torch::tensor({info.step}, torch::kInt64));
    archive.write("wall_s", torch::tensor({info.wall_s}, torch::kFloat64));
    archive.write("losses", torch::tensor({info.loss, info.valid_loss, info.valid_zero_prediction},
                                          torch::kFloat64));
    archive.save_to(pt);
  }
  const std::string original = h5 + ".original";
  fs::rename(h5, original);

  r.until = 0;
  r.resume = true;
  for (int attempt = 0; attempt < 2; ++attempt) {
    try {
      if (attempt == 0) {
        train(r);
      } else {
        RolloutRequest q;
        q.run = r.out;
        q.quiet = true;
        rollout(q);
      }
      FAIL() << "expected an InputError";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("latest.pt: a LibTorch archive"), std::string::npos)
          << e.what();
    }
  }
  EXPECT_FALSE(fs::exists(h5));

  EXPECT_EQ(convert_torch_checkpoint(r.out).step, 3);
  EXPECT_THROW(convert_torch_checkpoint(r.out), InputError);  // once
  const CheckpointContents a = read_checkpoint_contents(h5, read_checkpoint_bytes(h5));
  const CheckpointContents b = read_checkpoint_contents(original, read_checkpoint_bytes(original));
  ASSERT_EQ(a.model.size(), b.model.size());
  for (size_t i = 0; i < a.model.size(); ++i) {
    EXPECT_EQ(a.model[i].name, b.model[i].name);
    EXPECT_TRUE(torch::equal(a.model[i].value, b.model[i].value)) << a.model[i].name;
  }
  ASSERT_EQ(a.slots.size(), b.slots.size());
  for (size_t i = 0; i < a.slots.size(); ++i) {
    EXPECT_EQ(a.slots[i].parameter, b.slots[i].parameter);
    EXPECT_EQ(a.slots[i].step, b.slots[i].step);
    EXPECT_TRUE(torch::equal(a.slots[i].exp_avg, b.slots[i].exp_avg));
    EXPECT_TRUE(torch::equal(a.slots[i].exp_avg_sq, b.slots[i].exp_avg_sq));
  }
  // (The learning rate is the schedule's, set before every step: LibTorch's archive loader never
  // restored it, the conversion does not either.)
  ASSERT_EQ(a.groups.size(), 1u);
  EXPECT_EQ(a.groups[0].eps, b.groups[0].eps);
  EXPECT_EQ(a.state.step, 3);
  EXPECT_EQ(a.state.wall_s, b.state.wall_s);
  EXPECT_EQ(train(r).steps, 6);
}

// Without a valid split the run validates on training frames and says so (one warning line, and
// valid_split in train_stats.json); a damaged valid split is an error, not a silent fallback.
TEST(ValidSplit, MissingIsSaidDamagedIsAnError) {
  const fs::path dir = fresh_dir("valid_split");
  fs::create_directories(dir / "data");
  write_split(dir / "data", "train", 2, 8);
  TrainRequest r;
  r.config_path = write_config(dir, dir / "data", "mgn", 4);
  r.out = (dir / "run").string();
  r.threads = 1;
  r.quiet = true;
  ::testing::internal::CaptureStderr();
  train(r);
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("no valid split"), std::string::npos) << err;
  EXPECT_EQ(read_train_stats(run_stats_path(r.out)).valid_split, "train");
  std::ofstream(dir / "data" / "valid.h5") << "damaged";
  r.out = (dir / "run2").string();
  try {
    train(r);
    FAIL() << "a damaged valid split trained";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("valid.h5"), std::string::npos) << e.what();
  }
}

// The training loss of every logged step, in order.
std::vector<double> logged_losses(const std::string& run) {
  std::ifstream in(run_log_path(run));
  std::string line;
  std::getline(in, line);
  std::vector<double> losses;
  while (std::getline(in, line)) {
    const auto a = line.find(','), b = line.find(',', a + 1), c = line.find(',', b + 1);
    losses.push_back(std::stod(line.substr(b + 1, c - b - 1)));
  }
  return losses;
}

// With a parameter average, validation measures what the checkpoint predicts with (the average)
// while training is the same step for step: the losses of a run with and without the average are
// bit-identical, their validation losses are not.
TEST_F(PipelineTest, ValidationMeasuresTheAverageTrainingIsUnchanged) {
  TrainRequest plain;
  plain.config_path = write_config(dir_, dir_ / "data", "mgn", 30);
  plain.overrides = {"valid_every=10"};
  plain.out = (dir_ / "run_validate_plain").string();
  plain.threads = 1;
  plain.quiet = true;
  TrainRequest averaged = plain;
  averaged.overrides.push_back("optimizer.ema_decay=0.9");
  averaged.out = (dir_ / "run_validate_average").string();
  const TrainResult a = train(plain);
  const TrainResult b = train(averaged);
  const std::vector<double> losses = logged_losses(plain.out);
  ASSERT_EQ(losses.size(), 30u);
  EXPECT_EQ(losses, logged_losses(averaged.out));
  EXPECT_TRUE(std::isfinite(b.final_valid_loss));
  EXPECT_NE(a.final_valid_loss, b.final_valid_loss);
}

// Pushforward (features.pushforward): the sample at frame t is the model's own rollout from the
// truth at t-1-u and t-u, and its target the truth corrected for noise plus drift.
class Pushforward : public PipelineTest {
 protected:
  void SetUp() override {
    config_.data = (dir_ / "data").string();
    config_.model.levels = 2;
    config_.features.noise_std = 1e-3;
    config_.features.noise_gamma = 0.1;
    config_.features.pushforward = 3;
    train_ = std::make_unique<Dataset>(Dataset::open_split(config_.data, "train"));
    resolved_ = resolve_model(config_, *train_);
    store_ = std::make_unique<GraphStore>(config_.model.seeding, resolved_.levels,
                                          std::vector<std::string>{});
  }
  // The same refs and the same noise each call.
  TrainBatch batch(const std::vector<SampleRef>& refs, const Predictor* predictor) {
    std::vector<at::Generator> generators;
    for (size_t k = 0; k < refs.size(); ++k)
      generators.push_back(at::detail::createCPUGenerator(11 + k));
    return make_train_batch(resolved_, config_, *train_, *store_, refs, &generators, predictor);
  }
  torch::Tensor frames(int64_t trajectory) const {
    auto x = train_->read(trajectory, "world_pos", 0, train_->num_frames(trajectory));
    const int64_t n = train_->mesh(trajectory).num_nodes();
    return torch::tensor(x).reshape({train_->num_frames(trajectory), n, 2});
  }
  // A quiet 2-thread training request on the fixture's data, in a fresh folder named by `tag`.
  TrainRequest small_run(const std::string& tag, int64_t steps) const {
    const fs::path dir = fresh_dir(tag);
    TrainRequest r;
    r.config_path = write_config(dir, dir_ / "data", "bsms", steps);
    r.out = (dir / "run").string();
    r.threads = 2;
    r.quiet = true;
    return r;
  }
  // Each set of overrides makes `bsms train` an InputError whose message names `key`.
  static void expect_refused(TrainRequest r, const std::vector<std::vector<std::string>>& sets,
                             const std::string& key) {
    r.out = (fs::path(r.out).parent_path() / "bad").string();
    for (const auto& overrides : sets) {
      r.overrides = overrides;
      try {
        train(r);
        ADD_FAILURE() << overrides.back() << ": expected an InputError";
      } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
      }
    }
  }
  TrainConfig config_;
  std::unique_ptr<Dataset> train_;
  ResolvedModel resolved_;
  std::unique_ptr<GraphStore> store_;
};

TEST_F(Pushforward, AModelThatPredictsNothingExtrapolatesTheVelocity) {
  // Zero acceleration: u steps from frames t-1-u, t-u move the solved nodes on at the velocity
  // x_{t-u} - x_{t-1-u}; pinned nodes keep the truth. Frame 2 can only unroll 1 step, frame 1 none.
  const Predictor zero = [](const Batch& b) { return torch::zeros_like(b.cur); };
  for (const SampleRef ref : {SampleRef{2, 7}, SampleRef{4, 2}, SampleRef{1, 1}}) {
    const int64_t t = ref.frame, u = std::min<int64_t>(3, t - 1);
    const auto x = frames(ref.trajectory);
    const TrainBatch plain = batch({ref}, nullptr);
    const TrainBatch pushed = batch({ref}, &zero);
    const auto mask = plain.batch.mask.unsqueeze(1);
    const auto noise = plain.batch.noise;  // what the plain batch added to x_t
    const auto v = x[t - u] - x[t - u - 1];
    const auto cur = torch::where(mask, x[t - u] + u * v, x[t]);
    const auto prev = torch::where(mask, x[t - u] + (u - 1) * v, x[t - 1]);
    EXPECT_TRUE(torch::allclose(pushed.batch.cur, cur + noise, 1e-6, 1e-7)) << t;
    EXPECT_TRUE(torch::allclose(pushed.batch.prev, prev, 1e-6, 1e-7)) << t;
    EXPECT_TRUE(torch::allclose(pushed.batch.noise, noise + (cur - x[t]), 1e-6, 1e-7)) << t;
    const auto target = x[t + 1] + 0.9 * (noise + cur - x[t]) - 2 * (cur + noise) + prev;
    EXPECT_TRUE(
        torch::allclose(pushed.target, torch::where(mask, target, pushed.target), 1e-6, 1e-7))
        << t;
    // pushforward_target "acceleration": the same inputs, and the frame's own target.
    config_.features.pushforward_target = "acceleration";
    const TrainBatch kept = batch({ref}, &zero);
    config_.features.pushforward_target = "position";
    EXPECT_TRUE(torch::equal(kept.batch.inputs, pushed.batch.inputs)) << t;
    EXPECT_TRUE(torch::allclose(kept.target, plain.target, 1e-5, 1e-7)) << t;
    if (u == 0) {
      EXPECT_TRUE(torch::equal(pushed.batch.inputs, plain.batch.inputs));
      EXPECT_TRUE(torch::equal(pushed.target, plain.target));
    } else {
      EXPECT_GT((pushed.batch.cur - plain.batch.cur).abs().max().item<double>(), 1e-5) << t;
    }
  }
}

TEST_F(Pushforward, APerfectModelLeavesTheSampleAsItWas) {
  // The plate's exact law, a = g - c (x_t - x_{t-1}) (plate_data.hpp): rolling it out reproduces
  // the truth, so the pushed-forward batch is the plain one (to float rounding).
  const Predictor exact = [](const Batch& b) {
    auto a = -0.1 * (b.cur - b.prev);
    a.select(1, 1).add_(-0.0005);
    return a;
  };
  const std::vector<SampleRef> refs = {{0, 9}, {3, 5}};
  const TrainBatch plain = batch(refs, nullptr);
  const TrainBatch pushed = batch(refs, &exact);
  EXPECT_TRUE(torch::allclose(pushed.batch.cur, plain.batch.cur, 1e-5, 1e-7));
  EXPECT_TRUE(torch::allclose(pushed.batch.inputs, plain.batch.inputs, 1e-4, 1e-6));
  EXPECT_TRUE(torch::allclose(pushed.target, plain.target, 1e-4, 1e-7));
}

TEST_F(Pushforward, TrainsAndIsAnInputErrorOutOfRange) {
  TrainRequest r = small_run("pushforward", 120);
  r.overrides = {"features.pushforward=2", "features.pushforward_from=40"};
  const TrainResult result = train(r);
  EXPECT_EQ(result.steps, 120);
  EXPECT_TRUE(std::isfinite(result.final_valid_loss));
  const Json saved = load_json_file(run_config_path(r.out))["config"];
  EXPECT_EQ(saved["features"]["pushforward"].get<int>(), 2);
  EXPECT_EQ(saved["features"]["pushforward_from"].get<int>(), 40);
  // The same run without it: identical losses up to step 39, different from step 40 on.
  const std::string pushed_run = r.out;
  r.out = (fs::path(pushed_run).parent_path() / "plain").string();
  r.overrides = {};
  train(r);
  const auto pushed = logged_losses(pushed_run), plain = logged_losses(r.out);
  ASSERT_EQ(pushed.size(), 120u);
  ASSERT_EQ(plain.size(), 120u);
  for (size_t i = 0; i < 39; ++i) EXPECT_EQ(pushed[i], plain[i]) << "step " << i + 1;
  EXPECT_NE(pushed[39], plain[39]);
  expect_refused(
      r,
      {{"features.pushforward=-1"}, {"features.pushforward=101"}, {"features.pushforward_from=-5"}},
      "features.pushforward");
}

// Velocity history (features.history): the inputs carry x_t - x_{t-1} and the velocities before
// it from the true frames, filled at constant velocity before frame 0; training noise is on x_t
// only, or (history_noise "walk") walks back from it in steps of noise_std / sqrt(history).
TEST_F(Pushforward, HistoryInputsAreTheVelocitiesBefore) {
  config_.features.pushforward = 0;
  config_.features.history = 3;
  const double sigma = config_.features.noise_std;
  config_.features.noise_std = 0.0;
  resolved_ = resolve_model(config_, *train_);
  ASSERT_EQ(resolved_.spec.history, 3);
  ASSERT_EQ(resolved_.spec.input_size(),
            3 * 2 + resolved_.spec.num_node_types + (resolved_.spec.has_walls() ? 4 : 0));
  for (const SampleRef ref : {SampleRef{2, 7}, SampleRef{4, 2}, SampleRef{1, 1}}) {
    const int64_t t = ref.frame;
    const auto x = frames(ref.trajectory);
    const TrainBatch b = batch({ref}, nullptr);
    // x_{t-k} for k >= 0, extended before frame 0 at the first velocity.
    auto at = [&](int64_t f) { return f >= 0 ? x[f] : x[0] + f * (x[1] - x[0]); };
    EXPECT_TRUE(torch::allclose(b.batch.inputs.slice(1, 0, 2), at(t) + b.batch.noise - at(t - 1),
                                1e-6, 1e-7))
        << t;
    EXPECT_TRUE(torch::allclose(b.batch.inputs.slice(1, 2, 4), at(t - 1) - at(t - 2), 1e-6, 1e-7))
        << t;
    EXPECT_TRUE(torch::allclose(b.batch.inputs.slice(1, 4, 6), at(t - 2) - at(t - 3), 1e-6, 1e-7))
        << t;
  }
  // With noise: velocity t gets the position noise n, velocity t-1 n - d1, t-2 n - d1 - d2, with
  // d ~ N(0, sigma^2 / 3) on the solved nodes; pinned nodes keep the truth.
  config_.features.noise_std = sigma;
  {
    const SampleRef ref{3, 6};
    config_.features.noise_std = 0.0;
    const TrainBatch clean = batch({ref}, nullptr);
    config_.features.noise_std = sigma;
    const TrainBatch only_now = batch({ref}, nullptr);  // history_noise "off"
    const auto now = only_now.batch.noise.index({only_now.batch.mask});
    const auto off = (only_now.batch.inputs - clean.batch.inputs).index({only_now.batch.mask});
    EXPECT_TRUE(torch::allclose(off.slice(1, 0, 2), now, 1e-5, 1e-6));
    EXPECT_LT(off.slice(1, 2, 6).abs().max().item<double>(), 1e-6);
    EXPECT_GT(now.abs().max().item<double>(), 0.1 * sigma);
    config_.features.history_noise = "walk";
    const TrainBatch noisy = batch({ref}, nullptr);
    config_.features.history_noise = "off";
    const auto mask = noisy.batch.mask;
    const auto n = noisy.batch.noise.index({mask});
    const auto dv = (noisy.batch.inputs - clean.batch.inputs).slice(1, 0, 6).index({mask});
    EXPECT_TRUE(torch::allclose(dv.slice(1, 0, 2), n, 1e-5, 1e-6));
    const auto d1 = dv.slice(1, 0, 2) - dv.slice(1, 2, 4),
               d2 = dv.slice(1, 2, 4) - dv.slice(1, 4, 6);
    for (const auto& d : {d1, d2}) {
      const double rms = d.square().mean().sqrt().item<double>();
      EXPECT_GT(rms, 0.6 * sigma / std::sqrt(3.0)) << rms;
      EXPECT_LT(rms, 1.4 * sigma / std::sqrt(3.0)) << rms;
    }
    const auto pinned = ~mask;
    ASSERT_GT(pinned.sum().item<int64_t>(), 0);
    EXPECT_TRUE(
        torch::equal(noisy.batch.inputs.index({pinned}), clean.batch.inputs.index({pinned})));
  }
  // Pushed forward by a model that predicts nothing, the history is the model's own: from
  // x_{t-u-1} .. x_{t-u}, u steps at the velocity v = x_{t-u} - x_{t-u-1} on the solved nodes.
  config_.features.pushforward = 3;
  config_.features.noise_std = 0.0;
  const Predictor zero = [](const Batch& b) { return torch::zeros_like(b.cur); };
  const SampleRef ref{2, 7};
  const auto x = frames(ref.trajectory);
  const TrainBatch pushed = batch({ref}, &zero);
  const auto mask = pushed.batch.mask.unsqueeze(1);
  const auto v = x[4] - x[3];
  EXPECT_TRUE(torch::allclose(pushed.batch.inputs.slice(1, 2, 4),
                              torch::where(mask, v, x[6] - x[5]), 1e-6, 1e-7));
  EXPECT_TRUE(torch::allclose(pushed.batch.inputs.slice(1, 4, 6),
                              torch::where(mask, v, x[5] - x[4]), 1e-6, 1e-7));
  // A run trains and rolls out with it; out of range, or without a velocity input, it is an
  // InputError naming the key.
  TrainRequest r = small_run("history", 40);
  r.overrides = {"features.history=2"};
  EXPECT_EQ(train(r).steps, 40);
  EXPECT_EQ(load_json_file(run_config_path(r.out))["features_resolved"]["history"].get<int>(), 2);
  RolloutRequest q;
  q.run = r.out;
  q.quiet = true;
  const RolloutMetrics metrics = rollout(q);
  EXPECT_TRUE(std::isfinite(RolloutMetrics::rmse(metrics.rmse_all, "world_pos")));
  expect_refused(r,
                 {{"features.history=0"},
                  {"features.history=11"},
                  {"features.history=2", "features.output=velocity"},
                  {"features.history_noise=walk"}},
                 "features.history");
}

TEST_F(PipelineTest, BadConfigsAndCheckpointsAreInputErrors) {
  const fs::path dir = fresh_dir("bad");
  const std::string config = (dir / "c.json").string();
  std::ofstream(config) << R"({"data": ")" << (dir_ / "data").string()
                        << R"(", "steps": 5, "model": {"type": "bsms", "lattent": 8}})";
  TrainRequest r;
  r.config_path = config;
  r.out = (dir / "run").string();
  r.quiet = true;
  expect_input_error([&] { train(r); }, "model.lattent");
  r.config_path = write_config(dir, dir_ / "data", "bsms", 5);
  r.overrides = {"data=" + (dir / "nothing").string()};
  EXPECT_THROW(train(r), InputError);
  r.overrides = {};
  train(r);
  // A truncated checkpoint.
  const std::string checkpoint = run_checkpoint_path(r.out);
  fs::resize_file(checkpoint, fs::file_size(checkpoint) / 3);
  RolloutRequest q;
  q.run = r.out;
  q.quiet = true;
  EXPECT_THROW(rollout(q), InputError);
  q.run = (dir / "not_a_run").string();
  EXPECT_THROW(rollout(q), InputError);
}

}  // namespace
}  // namespace bsms
