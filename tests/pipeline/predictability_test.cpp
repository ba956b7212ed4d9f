// bsms experiment predictability: the crossing read off a sweep, the persistence of one-step
// errors against AR(1) sequences of known correlation, and the whole experiment on a small
// generated dataset (the re-solve reproduces the stored frames; kicks land at the asked size and
// grow the error with their size).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "core/error.hpp"
#include "data/dataset/dataset.hpp"
#include "data/generate/family.hpp"
#include "data/generate/generator.hpp"
#include "pipeline/experiments/predictability.hpp"
#include "pipeline/runs/rollout_metrics.hpp"
#include "tests/temp_dir.hpp"

namespace {

namespace fs = std::filesystem;
using namespace bsms;

// A path that does not exist yet, in a new folder of this test process.
fs::path fresh_dir(const std::string& name) {
  return bsms::testing::unique_temp_dir("predictability") / name;
}

TEST(Predictability, LogLogCrossingInterpolatesInLogs) {
  // y = 0.05 x^2 crosses 0.1 at x = sqrt(2), found exactly between x = 1 and x = 2.
  EXPECT_NEAR(log_log_crossing({0.5, 1, 2, 4}, {0.0125, 0.05, 0.2, 0.8}, 0.1), std::sqrt(2.0),
              1e-12);
  EXPECT_DOUBLE_EQ(log_log_crossing({1, 2}, {0.1, 0.3}, 0.1), 1.0);
  EXPECT_TRUE(std::isnan(log_log_crossing({1, 2}, {0.2, 0.3}, 0.1)));    // above throughout
  EXPECT_TRUE(std::isnan(log_log_crossing({1, 2}, {0.01, 0.03}, 0.1)));  // below throughout
  EXPECT_TRUE(std::isnan(log_log_crossing({1}, {0.1}, 0.1)));
  EXPECT_THROW(log_log_crossing({1, 2}, {0.1}, 0.1), std::invalid_argument);
}

// A rollout file whose bodies' predictions are off by a per-body error sequence e (the same for
// all of a body's nodes), drawn by `next(previous)` per component.
template <typename Next>
void write_rollout(const std::string& path, int64_t frames, Next next) {
  DatasetWriter w(path, "{}", 2, 0.04);
  std::mt19937_64 rng(7);
  for (int traj = 0; traj < 3; ++traj) {
    Trajectory t;
    t.mesh.dim = 2;
    t.mesh.cell_size = 3;
    t.mesh.cells = {0, 1, 2, 3, 4, 5};
    t.mesh.mesh_pos = {0, 0, 1, 0, 0, 1, 2, 0, 3, 0, 2, 1};
    t.mesh.node_type.assign(6, 0);
    t.mesh.body_id = {0, 0, 0, 1, 1, 1};
    t.num_frames = frames;
    auto& pred = t.fields["world_pos"];
    auto& truth = t.fields["target_world_pos"];
    double e[2][2] = {{0, 0}, {0, 0}};
    for (int64_t f = 0; f < frames; ++f) {
      for (int b = 0; b < 2; ++b)
        for (int a = 0; a < 2; ++a) e[b][a] = f < 2 ? 0.0 : next(e[b][a], f == 2, rng);
      for (int i = 0; i < 6; ++i)
        for (int a = 0; a < 2; ++a) {
          const float x = t.mesh.mesh_pos[i * 2 + a] + 0.01f * static_cast<float>(f);
          truth.push_back(x);
          pred.push_back(x + static_cast<float>(1e-3 * e[i / 3][a]));
        }
    }
    w.add(t);
  }
  w.commit();
}

TEST(Predictability, PersistenceOfOneStepErrorsMatchesKnownSequences) {
  const fs::path dir = fresh_dir("persistence");
  fs::create_directories(dir);
  // AR(1) with correlation 0.6: rho_L = 0.6^L, tau = 1 + 2 (0.6 + ... + 0.6^10).
  const std::string ar = (dir / "ar.h5").string();
  write_rollout(ar, 1500, [](double prev, bool first, std::mt19937_64& rng) {
    std::normal_distribution<double> n(0.0, 1.0);
    return first ? n(rng) : 0.6 * prev + std::sqrt(1 - 0.36) * n(rng);
  });
  const ErrorPersistence p = one_step_error_persistence(ar);
  ASSERT_EQ(p.autocorrelation.size(), 10u);
  EXPECT_NEAR(p.autocorrelation[0], 0.6, 0.03);
  EXPECT_NEAR(p.autocorrelation[1], 0.36, 0.04);
  double tau = 1;
  for (int L = 1; L <= 10; ++L) tau += 2 * std::pow(0.6, L);
  EXPECT_NEAR(p.tau, tau, 0.35);
  EXPECT_NEAR(p.rho_ar1, (tau - 1) / (tau + 1), 0.04);
  EXPECT_EQ(p.body_frames, 3 * 2 * 1498);

  // Independent errors: nothing persists (tau stops at the first lag, which is ~0).
  const std::string white = (dir / "white.h5").string();
  write_rollout(white, 1500, [](double, bool, std::mt19937_64& rng) {
    return std::normal_distribution<double>(0.0, 1.0)(rng);
  });
  const ErrorPersistence w = one_step_error_persistence(white);
  EXPECT_NEAR(w.autocorrelation[0], 0.0, 0.03);
  EXPECT_LT(w.tau, 1.07);

  // A constant bias persists at every lag: tau = 1 + 2 * 10.
  const std::string bias = (dir / "bias.h5").string();
  write_rollout(bias, 40, [](double, bool, std::mt19937_64&) { return 1.0; });
  const ErrorPersistence c = one_step_error_persistence(bias, 10);
  for (double r : c.autocorrelation) EXPECT_NEAR(r, 1.0, 1e-9);
  EXPECT_NEAR(c.tau, 21.0, 1e-6);
  EXPECT_NEAR(c.rho_ar1, 20.0 / 22.0, 1e-9);

  // A dataset that is not a rollout names the file.
  DatasetWriter plain((dir / "plain.h5").string(), "{}", 2, 0.04);
  plain.commit();
  try {
    one_step_error_persistence((dir / "plain.h5").string());
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("plain.h5"), std::string::npos) << e.what();
  }
}

TEST(Predictability, KicksLandAtTheirSizeAndGrowTheRolloutError) {
  const generate::FamilyConfig family =
      generate::load_family(std::string(BSMS_SOURCE_DIR) + "/configs/families/disks2d.json",
                            {"frames=12", "sample.count=[2, 3]", "sample.spacing=0.04",
                             "scene.background.element_size=0.06"});
  generate::GenerateOptions g;
  g.trajectories = 4;
  g.split = {0, 0, 1};
  g.seed = 5;
  g.threads = 2;
  g.out_dir = fresh_dir("data").string();
  generate::generate_dataset(family, g);

  PredictabilityOptions o;
  o.data = g.out_dir;
  o.out = fresh_dir("out").string();
  o.centre = 2e-4;
  o.rotation = 1e-4;
  o.scales = {0.5, 2.0};
  o.correlation = 0.7;
  o.draws = 3;
  o.threads = 2;
  o.quiet = true;
  const Json m = predictability_experiment(o);
  EXPECT_EQ(m["trajectories"].get<int64_t>(), 4);
  // Solved again without kicks, the trajectories are the stored ones, bit for bit.
  EXPECT_EQ(m["resolve_max_abs_diff_m"].get<double>(), 0.0);
  const Json& points = m["points"];
  ASSERT_EQ(points.size(), 6u);  // 2 scales x (independent, persistent, once)
  std::map<std::string, std::vector<double>> ratio;
  for (const Json& row : points) {
    SCOPED_TRACE(row.dump());
    EXPECT_EQ(row["failed_solves"].get<int>(), 0);
    const double scale = row["scale"].get<double>();
    // The first predicted frame's centre error is the kick's (RMS per component) within the
    // spread of ~2.5 bodies x 4 trajectories x 3 draws x 2 components.
    EXPECT_NEAR(row["first_step_parts"]["centre"].get<double>() / (2e-4 * scale), 1.0, 0.35);
    ratio[row["mode"].get<std::string>()].push_back(
        row["rmse_all_over_constant_velocity"].get<double>());
  }
  for (const auto& [mode, r] : ratio) {
    SCOPED_TRACE(mode);
    ASSERT_EQ(r.size(), 2u);
    EXPECT_GT(r[1], 1.5 * r[0]);  // 4x the kick: a larger error
  }
  // One kick drifts less than a kick at every frame of the same size.
  EXPECT_LT(ratio["once"][1], ratio["every, independent"][1]);
  EXPECT_TRUE(fs::exists(fs::path(o.out) / "predictability.md"));
  EXPECT_TRUE(fs::exists(fs::path(o.out) / "metrics.json"));
  EXPECT_FALSE(fs::exists(fs::path(o.out) / ".work"));

  // Bad input names what is wrong.
  PredictabilityOptions none = o;
  none.centre = 0;
  none.out = fresh_dir("none").string();
  EXPECT_THROW(predictability_experiment(none), InputError);
  PredictabilityOptions no_manifest = o;
  no_manifest.data = fresh_dir("empty").string();
  fs::create_directories(no_manifest.data);
  try {
    predictability_experiment(no_manifest);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("generate.json"), std::string::npos) << e.what();
  }
  // A run whose one-step rollout was made on other trajectories gives no base error here.
  const fs::path run = fresh_dir("run");
  fs::create_directories(run / "rollout_one_step");
  RolloutMetrics other;
  other.model = "bsms";
  other.split = "test";
  other.one_step = true;
  other.data = (fs::path(o.out) / "metrics.json").string();  // an existing file, not the data
  other.rmse_all_parts = MotionRmse{1e-4, 1e-4, 1e-4};
  {
    std::ofstream f(run / "rollout_one_step" / "metrics.json");
    f << to_json(other).dump();
  }
  PredictabilityOptions elsewhere = o;
  elsewhere.centre = 0;
  elsewhere.rotation = -1;
  elsewhere.run = run.string();
  elsewhere.out = fresh_dir("elsewhere").string();
  try {
    predictability_experiment(elsewhere);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("a one-step rollout on"), std::string::npos) << e.what();
  }
  PredictabilityOptions bad_scales = o;
  bad_scales.scales = {2.0, 1.0};
  EXPECT_THROW(predictability_experiment(bad_scales), InputError);

  // --solver-set: the same background size again changes nothing (the altered row is 0 m);
  // another size is another background mesh and another time step, a different solve.
  PredictabilityOptions same = o;
  same.scales = {1.0};
  same.correlation = 0;
  same.draws = 1;
  same.solver_set = {"scene.background.element_size=0.06"};
  same.out = fresh_dir("same").string();
  const Json s = predictability_experiment(same);
  ASSERT_EQ(s["points"].size(), 3u);  // independent, once, altered
  const Json& unchanged = s["points"].back();
  EXPECT_EQ(unchanged["mode"].get<std::string>(), "altered solver, no kicks");
  EXPECT_EQ(unchanged["rmse_all"].get<double>(), 0.0);
  PredictabilityOptions other_mesh = same;
  other_mesh.solver_set = {"scene.background.element_size=0.055"};
  other_mesh.out = fresh_dir("other_mesh").string();
  const Json a = predictability_experiment(other_mesh);
  const Json& altered = a["points"].back();
  EXPECT_GT(altered["rmse_all"].get<double>(), 1e-5);
  // The bodies still move as the scene says: far closer than constant velocity.
  EXPECT_LT(altered["rmse_all_over_constant_velocity"].get<double>(), 0.5);
  EXPECT_EQ(a["solver_set"][0].get<std::string>(), "scene.background.element_size=0.055");
  for (const char* bad : {"background.element_size=0.05", "scene.background.size=0.05"}) {
    SCOPED_TRACE(bad);
    PredictabilityOptions wrong = same;
    wrong.solver_set = {bad};
    wrong.out = fresh_dir("wrong").string();
    EXPECT_THROW(predictability_experiment(wrong), InputError);
  }
}

}  // namespace
