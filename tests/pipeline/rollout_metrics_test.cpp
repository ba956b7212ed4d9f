// RUN/rollout/metrics.json (pipeline/runs/rollout_metrics.hpp): what bsms rollout writes its reader
// reads back unchanged (NaN as null), and a missing, mistyped or unknown key is one InputError
// naming the file and the key.
#include "pipeline/runs/rollout_metrics.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/error.hpp"

namespace bsms {
namespace {

RolloutMetrics lagrangian_metrics() {
  RolloutMetrics m;
  m.model = "bsms";
  m.split = "test";
  m.data = "runs/data/test.h5";
  m.seeding = "minave";
  m.num_trajectories = 2;
  m.levels = 3;
  m.threads = 2;
  FieldRmse one;
  one.fields = {{"world_pos", 1e-3}, {"velocity", 0.02}};
  one.total = 0.014;
  m.rmse_1 = one;
  m.rmse_50 = one;
  m.rmse_all = one;
  m.rmse_per_step["world_pos"] = {1e-3, 2e-3, std::nan("")};  // a non-finite step
  m.rmse_trajectory_mean["1"] = one;
  m.rmse_trajectory_mean["all"] = one;
  m.rmse_all_constant_velocity = 0.5;
  m.rmse_all_parts = MotionRmse{6e-4, 2e-4, 7.75e-4};
  m.rmse_all_parts_constant_velocity = MotionRmse{0.45, 0.2, 0.1};
  m.rmse_all_deformation_rigid = 2e-3;
  m.per_trajectory = TrajectoryRmse{{3, 2}, {1e-3, 1.5e-3}, {0.4, 0.6}};
  m.rmse_all_ratio_interval = RatioInterval{1.5e-3, 3.5e-3};
  m.inverted_cells_per_step = {0.0, 0.0, 0.25};
  m.inverted_cells_max = 0.25;
  m.diverged = {{1, 7}};
  m.infer_ms_per_step = 3.5;
  m.solver_ms_per_frame = 17.0;
  m.speedup_vs_solver = 17.0 / 3.5;
  m.peak_rss_mb_infer = 300;
  m.num_nodes_mean = 49;
  m.train_ms_per_step = 12.0;
  m.peak_rss_mb_train = 400;
  m.train_steps = 60;
  return m;
}

// The error message of reading `json` as metrics, or "no error".
std::string metrics_error(const Json& json) {
  try {
    rollout_metrics_from_json(json, "RUN/rollout/metrics.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(RolloutMetricsFile, RoundTripsThroughTheFile) {
  const RolloutMetrics m = lagrangian_metrics();
  const Json written = Json::parse(to_json(m).dump());  // NaN becomes null in the file
  EXPECT_FALSE(written.contains("kind"));
  EXPECT_TRUE(written["rmse_per_step"]["world_pos"][2].is_null());
  const RolloutMetrics back = rollout_metrics_from_json(written, "metrics.json");
  EXPECT_EQ(Json::parse(to_json(back).dump()), written);
  EXPECT_TRUE(std::isnan(back.per_step("world_pos")[2]));
  EXPECT_EQ(back.rmse_all->at("world_pos"), 1e-3);
  EXPECT_TRUE(std::isnan(back.rmse_all->at("pressure")));
  EXPECT_EQ(back.diverged.size(), 1u);
  EXPECT_EQ(back.diverged[0].frame, 7);
  EXPECT_EQ(back.primary_field(), "world_pos");
  ASSERT_TRUE(back.rmse_all_parts && back.rmse_all_parts_constant_velocity);
  EXPECT_EQ(back.rmse_all_parts->deformation, 7.75e-4);
  EXPECT_EQ(back.rmse_all_parts_constant_velocity->centre, 0.45);
  EXPECT_EQ(back.rmse_all_deformation_rigid, 2e-3);
  EXPECT_FALSE(written.contains("one_step"));  // a rollout's file, as before the key existed
  RolloutMetrics forced = m;
  forced.one_step = true;
  const Json forced_json = Json::parse(to_json(forced).dump());
  EXPECT_TRUE(forced_json["one_step"].get<bool>());
  EXPECT_TRUE(rollout_metrics_from_json(forced_json, "metrics.json").one_step);
  ASSERT_TRUE(back.per_trajectory && back.rmse_all_ratio_interval);
  EXPECT_EQ(back.per_trajectory->steps, (std::vector<int64_t>{3, 2}));
  EXPECT_EQ(back.per_trajectory->constant_velocity[1], 0.6);
  EXPECT_EQ(back.rmse_all_ratio_interval->hi, 3.5e-3);
  // Files written before the split and the per-trajectory figures existed still read.
  Json older = written;
  older.erase("rmse_all_parts");
  older.erase("rmse_all_parts_constant_velocity");
  older.erase("rmse_all_deformation_rigid");
  older.erase("per_trajectory");
  older.erase("rmse_all_ratio_interval");
  const RolloutMetrics old_back = rollout_metrics_from_json(older, "metrics.json");
  EXPECT_FALSE(old_back.rmse_all_parts || old_back.rmse_all_parts_constant_velocity ||
               old_back.rmse_all_deformation_rigid || old_back.per_trajectory ||
               old_back.rmse_all_ratio_interval);
  EXPECT_EQ(Json::parse(to_json(old_back).dump()), older);

  // Eulerian: "kind", the persistence reference, no cells; absent figures are null.
  RolloutMetrics e = m;
  e.eulerian = true;
  e.rmse_per_step = {{"velocity", {0.1}}, {"pressure", {2.0}}};
  e.rmse_1_persistence = FieldRmse{{{"velocity", 0.2}, {"pressure", 3.0}}, 2.1};
  e.rmse_all_persistence = e.rmse_1_persistence;
  e.rmse_1 = std::nullopt;
  e.solver_ms_per_frame = e.speedup_vs_solver = std::nullopt;
  e.train_steps = std::nullopt;
  const Json ej = to_json(e);
  EXPECT_EQ(ej["kind"], "eulerian");
  EXPECT_FALSE(ej.contains("inverted_cells_max"));
  EXPECT_FALSE(ej.contains("train_steps"));
  EXPECT_TRUE(ej["rmse_1"].is_null());
  const RolloutMetrics eb = rollout_metrics_from_json(ej, "metrics.json");
  EXPECT_TRUE(eb.eulerian);
  EXPECT_FALSE(eb.rmse_1.has_value());
  EXPECT_FALSE(eb.solver_ms_per_frame.has_value());
  EXPECT_EQ(eb.rmse_all_persistence->at("velocity"), 0.2);
  EXPECT_EQ(eb.primary_field(), "velocity");
  EXPECT_EQ(to_json(eb), ej);
  // nlohmann's conversion: the Json callers of rollout() hold.
  const Json implicit = m;
  EXPECT_EQ(implicit.dump(), to_json(m).dump());  // (NaN != NaN: compare the text)
}

// The references' table by hand: per trajectory the RMSE over its first h steps, then the plain
// mean over trajectories; horizons past the longest trajectory are left out.
TEST(HorizonRmse, AveragesEachTrajectorysRmseOverItsFirstSteps) {
  HorizonRmse table;
  EXPECT_TRUE(table.result().empty());
  // Trajectory a: 12 steps, MSE 1 on steps 0..9 and 16 after; b: 3 steps of MSE 4.
  std::vector<double> a(12, 1.0);
  a[10] = a[11] = 16.0;
  table.add({{"world_pos", a}, {"velocity", std::vector<double>(12, 9.0)}});
  table.add({{"world_pos", {4.0, 4.0, 4.0}}, {"velocity", {0.0, 0.0, 0.0}}});
  const auto r = table.result();
  ASSERT_EQ(r.size(), 3u);  // "1", "10", "all": 20 and more exceed 12 steps
  EXPECT_DOUBLE_EQ(r.at("1").at("world_pos"), (1.0 + 2.0) / 2);
  EXPECT_DOUBLE_EQ(r.at("10").at("world_pos"), (1.0 + 2.0) / 2);  // b: its 3 steps
  EXPECT_DOUBLE_EQ(r.at("all").at("world_pos"), (std::sqrt((10.0 + 32.0) / 12) + 2.0) / 2);
  EXPECT_DOUBLE_EQ(r.at("all").at("velocity"), (3.0 + 0.0) / 2);
  const double pos = r.at("all").at("world_pos"), vel = r.at("all").at("velocity");
  EXPECT_DOUBLE_EQ(r.at("all").total, std::sqrt((pos * pos + vel * vel) / 2));
}

TEST(RolloutMetricsFile, HorizonTableRoundTripsAndIsChecked) {
  const Json written = Json::parse(to_json(lagrangian_metrics()).dump());
  ASSERT_TRUE(written.contains("rmse_trajectory_mean"));
  EXPECT_EQ(written["rmse_trajectory_mean"]["all"]["world_pos"], 1e-3);
  const RolloutMetrics back = rollout_metrics_from_json(written, "metrics.json");
  EXPECT_EQ(back.rmse_trajectory_mean.size(), 2u);
  Json bad = written;
  bad["rmse_trajectory_mean"]["7"] = bad["rmse_trajectory_mean"]["1"];
  EXPECT_NE(metrics_error(bad).find("rmse_trajectory_mean"), std::string::npos);
  Json older = written;  // written before the table existed
  older.erase("rmse_trajectory_mean");
  EXPECT_TRUE(rollout_metrics_from_json(older, "metrics.json").rmse_trajectory_mean.empty());
}

TEST(RolloutMetricsFile, ReaderIsStrictAndNamesFileAndKey) {
  const Json good = to_json(lagrangian_metrics());
  EXPECT_EQ(metrics_error(good), "no error");
  Json missing = good;
  missing.erase("infer_ms_per_step");
  const std::string e1 = metrics_error(missing);
  EXPECT_NE(e1.find("RUN/rollout/metrics.json"), std::string::npos) << e1;
  EXPECT_NE(e1.find("infer_ms_per_step"), std::string::npos) << e1;
  Json typed = good;
  typed["threads"] = "two";
  EXPECT_NE(metrics_error(typed).find("'threads'"), std::string::npos) << metrics_error(typed);
  Json unknown = good;
  unknown["rmse_100"] = 1.0;
  EXPECT_NE(metrics_error(unknown).find("unknown key 'rmse_100'"), std::string::npos);
  Json nested = good;
  nested["rmse_all"]["world_pos"] = "small";
  EXPECT_NE(metrics_error(nested).find("rmse_all.world_pos"), std::string::npos)
      << metrics_error(nested);
  Json no_total = good;
  no_total["rmse_50"].erase("total");
  EXPECT_NE(metrics_error(no_total).find("rmse_50.total"), std::string::npos);
  Json no_cells = good;  // a Lagrangian file without its stability figures
  no_cells.erase("inverted_cells_per_step");
  EXPECT_NE(metrics_error(no_cells).find("inverted_cells_per_step"), std::string::npos);
  Json eulerian = good;  // kind says Eulerian: the persistence reference is required
  eulerian["kind"] = "eulerian";
  EXPECT_NE(metrics_error(eulerian).find("rmse_1_persistence"), std::string::npos);
  Json parts = good;
  parts["rmse_all_parts"].erase("rotation");
  EXPECT_NE(metrics_error(parts).find("rmse_all_parts.rotation"), std::string::npos)
      << metrics_error(parts);
  Json extra_part = good;
  extra_part["rmse_all_parts_constant_velocity"]["spin"] = 1.0;
  EXPECT_NE(metrics_error(extra_part).find("rmse_all_parts_constant_velocity.spin"),
            std::string::npos)
      << metrics_error(extra_part);
  Json ragged = good;  // arrays of different lengths
  ragged["per_trajectory"]["rmse_all"] = Json::array({1e-3});
  EXPECT_NE(metrics_error(ragged).find("per_trajectory"), std::string::npos)
      << metrics_error(ragged);
  Json fractional = good;
  fractional["per_trajectory"]["steps"] = Json::array({3, 2.5});
  EXPECT_NE(metrics_error(fractional).find("per_trajectory.steps"), std::string::npos)
      << metrics_error(fractional);
  Json reversed = good;
  reversed["rmse_all_ratio_interval"] = Json::array({0.2, 0.1});
  EXPECT_NE(metrics_error(reversed).find("rmse_all_ratio_interval"), std::string::npos)
      << metrics_error(reversed);
  for (const char* bad : {"gcn", "bsms+gcn", "bsms+", "+mgn", ""}) {
    Json model = good;
    model["model"] = bad;
    EXPECT_NE(metrics_error(model).find("'model'"), std::string::npos) << bad;
  }
  // An ensemble's metrics (members joined by "+") and a symmetrized rollout's read back.
  Json ensemble = good;
  ensemble["model"] = "bsms+mgn+bsms";
  ensemble["symmetries"] = 8;
  EXPECT_EQ(metrics_error(ensemble), "no error");
  EXPECT_EQ(rollout_metrics_from_json(ensemble, "m.json").symmetries, 8);
  EXPECT_FALSE(good.contains("symmetries"));  // written only when > 1
  Json no_symmetry = good;
  no_symmetry["symmetries"] = 0;
  EXPECT_NE(metrics_error(no_symmetry).find("'symmetries'"), std::string::npos);
}

// Every number is checked where it is read: RMSEs, times, counts and fractions out of their
// range name the file and the field.
TEST(RolloutMetricsFile, NumbersOutOfRangeNameTheField) {
  const Json good = to_json(lagrangian_metrics());
  const auto refused = [&](const std::string& pointer, const Json& value, const std::string& key) {
    Json bad = good;
    bad[Json::json_pointer(pointer)] = value;
    const std::string e = metrics_error(bad);
    EXPECT_NE(e.find("RUN/rollout/metrics.json: key '" + key + "'"), std::string::npos)
        << pointer << ": " << e;
  };
  refused("/rmse_all/world_pos", -0.5, "rmse_all.world_pos");
  refused("/rmse_1/total", -1e-9, "rmse_1.total");
  refused("/rmse_per_step/world_pos/1", -2.0, "rmse_per_step.world_pos.1");
  refused("/rmse_all_constant_velocity", -1.0, "rmse_all_constant_velocity");
  refused("/inverted_cells_max", 1.5, "inverted_cells_max");
  refused("/inverted_cells_per_step/0", -0.1, "inverted_cells_per_step.0");
  refused("/infer_ms_per_step", -3.0, "infer_ms_per_step");
  refused("/num_trajectories", -1, "num_trajectories");
  refused("/levels", 0, "levels");
  refused("/per_trajectory/rmse_all/0", -1.0, "per_trajectory.rmse_all.0");
  const std::string e = [&] {
    Json bad = good;
    bad["rmse_all"]["world_pos"] = -0.5;
    return metrics_error(bad);
  }();
  EXPECT_NE(e.find("must be a number >= 0 or null, got -0.5"), std::string::npos) << e;
}

// The bootstrap against its exact distribution: with 3 trajectories there are 27 equally likely
// ordered draws, so the interval's ends are quantiles of 27 known ratios.
TEST(BootstrapRatioInterval, MatchesTheExactDistributionOnSmallInputs) {
  const std::vector<int64_t> steps = {48, 30, 48};
  const std::vector<double> a = {0.02, 0.09, 0.03}, b = {0.2, 0.25, 0.3};
  std::vector<double> exact;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) {
        double num = 0, den = 0;
        for (int t : {i, j, k}) {
          num += static_cast<double>(steps[t]) * a[t] * a[t];
          den += static_cast<double>(steps[t]) * b[t] * b[t];
        }
        exact.push_back(std::sqrt(num / den));
      }
  std::sort(exact.begin(), exact.end());
  // P(ratio <= exact[m]) over the 27 draws; the bootstrap's 10 % and 90 % quantiles fall on the
  // first order statistics whose cumulative share passes them.
  auto exact_quantile = [&](double q) {
    for (size_t m = 0; m < exact.size(); ++m)
      if (static_cast<double>(m + 1) / 27.0 >= q) return exact[m];
    return exact.back();
  };
  const auto i = bootstrap_ratio_interval(steps, a, b, 0.8, 200000, 7);
  ASSERT_TRUE(i.has_value());
  EXPECT_NEAR(i->lo, exact_quantile(0.1), 0.02 * exact_quantile(0.1));
  EXPECT_NEAR(i->hi, exact_quantile(0.9), 0.02 * exact_quantile(0.9));
  EXPECT_GE(i->lo, exact.front());
  EXPECT_LE(i->hi, exact.back());
}

TEST(BootstrapRatioInterval, PropertiesOnRandomTrajectories) {
  std::mt19937_64 rng(3);
  std::lognormal_distribution<double> spread(0.0, 0.8);
  for (int trial = 0; trial < 20; ++trial) {
    SCOPED_TRACE("trial " + std::to_string(trial));
    const size_t n = 10 + static_cast<size_t>(trial) * 5;
    std::vector<int64_t> steps(n);
    std::vector<double> a(n), b(n);
    for (size_t k = 0; k < n; ++k) {
      steps[k] = 10 + static_cast<int64_t>(rng() % 40);
      b[k] = 0.25 * spread(rng);
      a[k] = 0.04 * spread(rng);
    }
    double num = 0, den = 0;
    for (size_t k = 0; k < n; ++k) {
      num += static_cast<double>(steps[k]) * a[k] * a[k];
      den += static_cast<double>(steps[k]) * b[k] * b[k];
    }
    const double point = std::sqrt(num / den);
    const auto i = bootstrap_ratio_interval(steps, a, b);
    ASSERT_TRUE(i.has_value());
    // The whole-sample ratio lies inside; a wider level gives a wider interval; the same seed
    // gives the same interval.
    EXPECT_LT(i->lo, point);
    EXPECT_GT(i->hi, point);
    const auto wide = bootstrap_ratio_interval(steps, a, b, 0.99);
    EXPECT_LE(wide->lo, i->lo);
    EXPECT_GE(wide->hi, i->hi);
    const auto again = bootstrap_ratio_interval(steps, a, b);
    EXPECT_EQ(again->lo, i->lo);
    EXPECT_EQ(again->hi, i->hi);
    // A run that is c times another on every trajectory: the interval is the point c.
    std::vector<double> scaled(n);
    for (size_t k = 0; k < n; ++k) scaled[k] = 0.7 * b[k];
    const auto exact = bootstrap_ratio_interval(steps, scaled, b);
    EXPECT_NEAR(exact->lo, 0.7, 1e-12);
    EXPECT_NEAR(exact->hi, 0.7, 1e-12);
  }
  // Four times the trajectories from the same law: about half the width (1 / sqrt(4)).
  auto width = [&](size_t n, uint64_t seed) {
    std::mt19937_64 g(seed);
    std::vector<int64_t> steps(n, 48);
    std::vector<double> a(n), b(n);
    for (size_t k = 0; k < n; ++k) {
      b[k] = 0.25 * spread(g);
      a[k] = 0.04 * spread(g);
    }
    const auto i = bootstrap_ratio_interval(steps, a, b);
    return i->hi - i->lo;
  };
  double small = 0, large = 0;
  for (uint64_t seed = 0; seed < 10; ++seed) {
    small += width(100, seed);
    large += width(400, 100 + seed);
  }
  EXPECT_GT(large / small, 0.35);
  EXPECT_LT(large / small, 0.65);
  // Too few trajectories or a zero reference: none; bad arguments throw.
  EXPECT_FALSE(bootstrap_ratio_interval({48}, {0.1}, {0.2}).has_value());
  EXPECT_FALSE(bootstrap_ratio_interval({48, 48}, {0.1, 0.1}, {0.0, 0.0}).has_value());
  EXPECT_THROW(bootstrap_ratio_interval({48, 48}, {0.1}, {0.2, 0.2}), std::invalid_argument);
  EXPECT_THROW(bootstrap_ratio_interval({48, 48}, {0.1, 0.1}, {0.2, 0.2}, 1.0),
               std::invalid_argument);
}

TEST(RolloutMetricsFile, MissingOrNonObjectFileIsNamed) {
  const std::string file = "/nonexistent/run/rollout/metrics.json";
  try {
    read_rollout_metrics(file);
    ADD_FAILURE() << "no error for a missing file";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(file), std::string::npos) << e.what();
  }
  EXPECT_NE(metrics_error(Json::array()).find("RUN/rollout/metrics.json"), std::string::npos);
  Json diverged = to_json(lagrangian_metrics());
  diverged["diverged"] = Json::array({7});
  EXPECT_NE(metrics_error(diverged).find("diverged.0"), std::string::npos)
      << metrics_error(diverged);
}

}  // namespace
}  // namespace bsms
