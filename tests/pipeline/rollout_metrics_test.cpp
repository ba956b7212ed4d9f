// RUN/rollout/metrics.json (pipeline/rollout_metrics.hpp): what bsms rollout writes its reader
// reads back unchanged (NaN as null), and a missing, mistyped or unknown key is one InputError
// naming the file and the key.
#include "pipeline/rollout_metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

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
  m.rmse_all_constant_velocity = 0.5;
  m.rmse_all_parts = MotionRmse{6e-4, 2e-4, 7.75e-4};
  m.rmse_all_parts_constant_velocity = MotionRmse{0.45, 0.2, 0.1};
  m.rmse_all_deformation_rigid = 2e-3;
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
  // Files written before the split existed have no parts and still read.
  Json older = written;
  older.erase("rmse_all_parts");
  older.erase("rmse_all_parts_constant_velocity");
  older.erase("rmse_all_deformation_rigid");
  const RolloutMetrics old_back = rollout_metrics_from_json(older, "metrics.json");
  EXPECT_FALSE(old_back.rmse_all_parts || old_back.rmse_all_parts_constant_velocity ||
               old_back.rmse_all_deformation_rigid);
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
  Json model = good;
  model["model"] = "gcn";
  EXPECT_NE(metrics_error(model).find("'model'"), std::string::npos);
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
