// Physical validity of rollouts (pipeline/rollout/validity_tally.hpp and RolloutMetrics::validity):
// the walls read from a scene, the tally's per-step means, per-trajectory and overall worst values,
// and the metrics.json round trip with its strict reader.
#include "pipeline/rollout/validity_tally.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <set>
#include <string>

#include "core/config.hpp"
#include "core/error.hpp"
#include "data/mpm/background.hpp"
#include "scene_text.hpp"

namespace bsms {
namespace {

TEST(ValidityTally, WallsComeFromTheScene) {
  const auto scene = testing::typed_scene(R"({"scene": {"dim": 2,
      "background": {"type": "box", "min": [0, -1], "max": [2, 1], "element_size": 0.04},
      "boundaries": [{"group": "left", "type": "slip"}, {"group": "bottom", "type": "fixed"}],
      "solver": {"end_time": 1.0}}})");
  const BoxWalls walls = scene_walls(scene, 2);
  ASSERT_EQ(walls.lo.size(), 2u);
  EXPECT_EQ(walls.lo[0], 0.0);
  EXPECT_EQ(walls.lo[1], -1.0);
  EXPECT_TRUE(std::isnan(walls.hi[0]) && std::isnan(walls.hi[1]));  // no right or top wall
  EXPECT_TRUE(scene_walls(testing::typed_scene("{}"), 2).empty());
  EXPECT_TRUE(scene_walls(testing::typed_scene(R"({"scene": {"dim": 2, "background": {"type": "box",
                  "min": [0, 0], "max": [1, 1], "element_size": 0.1}, "solver": {"end_time": 1.0}}})"),
                          2)
                  .empty());  // a box without named walls
}

// The typed scene of every shipped family, as a dataset generated from it stores it, has the walls
// its JSON names: per axis, the box's min (max) where its low (high) side is a named boundary;
// none when no side is named. The oracle reads the family's JSON, as scene_walls did before the
// scene was typed.
TEST(ValidityTally, ShippedFamiliesKeepTheirWalls) {
  const std::filesystem::path families =
      std::filesystem::path(BSMS_SOURCE_DIR) / "configs/families";
  std::set<std::string> walled;
  for (const auto& entry : std::filesystem::directory_iterator(families)) {
    const std::string path = entry.path().string();
    SCOPED_TRACE(path);
    const Json family = load_json_file(path);
    const Json& base = family.at("scene");
    const int dim = base.at("dim").get<int>();
    std::set<std::string> named;
    for (const auto& b : base.value("boundaries", Json::array()))
      if (b.contains("group")) named.insert(b.at("group").get<std::string>());
    BoxWalls expected;
    bool any = false;
    for (int a = 0; a < dim; ++a) {
      const bool lo = named.count(mpm::box_side_name(a, false)) > 0,
                 hi = named.count(mpm::box_side_name(a, true)) > 0;
      expected.lo.push_back(lo ? base["background"]["min"][a].get<double>() : std::nan(""));
      expected.hi.push_back(hi ? base["background"]["max"][a].get<double>() : std::nan(""));
      any = any || lo || hi;
    }
    if (!any || base["background"]["type"] != "box") expected = {};
    const BoxWalls walls = scene_walls(testing::typed_scene(family.dump(), dim), dim);
    ASSERT_EQ(walls.lo.size(), expected.lo.size());
    ASSERT_EQ(walls.hi.size(), expected.hi.size());
    for (size_t a = 0; a < expected.lo.size(); ++a) {
      EXPECT_TRUE(walls.lo[a] == expected.lo[a] ||
                  (std::isnan(walls.lo[a]) && std::isnan(expected.lo[a])))
          << a;
      EXPECT_TRUE(walls.hi[a] == expected.hi[a] ||
                  (std::isnan(walls.hi[a]) && std::isnan(expected.hi[a])))
          << a;
    }
    if (!walls.empty()) walled.insert(entry.path().filename().string());
  }
  // The box families with slip walls on every side; press and cantilever have none.
  EXPECT_EQ(walled, (std::set<std::string>{"bodies3d.json", "disks2d.json", "union2d.json"}));
}

TEST(ValidityTally, MeasuresApplyByMeshAndDimension) {
  TrajectoryMesh mesh;
  mesh.dim = 2;
  mesh.cell_size = 3;
  mesh.cells = {0, 1, 2};
  mesh.mesh_pos = {0, 0, 1, 0, 0, 1};
  mesh.node_type = {0, 0, 0};
  mesh.body_id = {0, 0, 0};
  EXPECT_FALSE(validity_for_mesh(mesh, 1, {}).has_value());
  const auto v = validity_for_mesh(mesh, 2, {});
  ASSERT_TRUE(v.has_value());
  EXPECT_EQ(v->num_cells(), 1);
  // Triangles in 3-D (a shell) have no volume: only the walls are measured.
  mesh.mesh_pos = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const auto shell = validity_for_mesh(mesh, 3, BoxWalls{{0, 0, 0}, {1, 1, 1}});
  ASSERT_TRUE(shell.has_value());
  EXPECT_EQ(shell->num_cells(), 0);
  EXPECT_TRUE(shell->has_walls());
}

FrameValidity frame(double overlap, int64_t inside, double outside, int64_t nodes_outside) {
  FrameValidity v;
  v.cell_measure = 2.0;
  v.overlap_measure = 2.0 * overlap;
  v.num_nodes = 10;
  v.nodes_in_other_body = inside;
  v.outside_walls_max = outside;
  v.nodes_outside_walls = nodes_outside;
  return v;
}

TEST(ValidityTally, MeansPerStepAndWorstPerTrajectory) {
  ValidityTally tally(true, true);
  tally.start_trajectory();  // three steps
  tally.add(0, frame(0.1, 1, 0.0, 0), frame(0.01, 0, 0.0, 0));
  tally.add(1, frame(0.3, 2, 0.5, 3), frame(0.02, 0, 0.0, 0));
  tally.add(2, frame(0.2, 0, 0.1, 1), frame(0.01, 1, 0.0, 0));
  tally.start_trajectory();  // diverged after one step
  tally.add(0, frame(0.5, 4, 0.2, 2), frame(0.03, 0, 0.0, 0));
  tally.start_trajectory();  // diverged at once: no step
  const auto m = tally.metrics();
  ASSERT_TRUE(m && m->model.overlap && m->truth.overlap && m->model.outside_walls);
  const ValidityCurve& overlap = *m->model.overlap;
  ASSERT_EQ(overlap.per_step.size(), 3u);
  EXPECT_NEAR(overlap.per_step[0], 0.3, 1e-15);  // mean of 0.1 and 0.5
  EXPECT_NEAR(overlap.per_step[1], 0.3, 1e-15);
  ASSERT_EQ(overlap.per_trajectory.size(), 3u);
  EXPECT_NEAR(overlap.per_trajectory[0], 0.3, 1e-15);
  EXPECT_NEAR(overlap.per_trajectory[1], 0.5, 1e-15);
  EXPECT_TRUE(std::isnan(overlap.per_trajectory[2]));
  EXPECT_NEAR(overlap.max, 0.5, 1e-15);
  EXPECT_NEAR(m->truth.overlap->max, 0.03, 1e-15);
  EXPECT_NEAR(m->model.nodes_in_other_body->per_step[0], 0.25, 1e-15);  // (1 + 4) / 2 / 10
  EXPECT_NEAR(m->model.outside_walls->max, 0.5, 1e-15);
  EXPECT_NEAR(m->model.nodes_outside_walls->per_trajectory[0], 0.3, 1e-15);
  EXPECT_EQ(m->truth.outside_walls->max, 0.0);
  // Only what applies is kept; nothing at all is none.
  ValidityTally walls_only(false, true);
  walls_only.start_trajectory();
  walls_only.add(0, frame(0.1, 1, 0.2, 1), frame(0, 0, 0, 0));
  const auto w = walls_only.metrics();
  ASSERT_TRUE(w.has_value());
  EXPECT_FALSE(w->model.overlap || w->model.nodes_in_other_body);
  EXPECT_TRUE(w->model.outside_walls && w->truth.nodes_outside_walls);
  EXPECT_FALSE(ValidityTally(false, false).metrics().has_value());
}

RolloutMetrics with_validity() {
  RolloutMetrics m;
  m.model = "bsms";
  m.split = "test";
  m.data = "d";
  m.seeding = "minave";
  m.inverted_cells_per_step = {0.0, 0.1};
  ValidityTally tally(true, true);
  tally.start_trajectory();
  tally.add(0, frame(0.1, 1, 0.0, 0), frame(0.01, 0, 0.0, 0));
  tally.add(1, frame(0.3, 2, 0.5, 3), frame(0.02, 0, 0.0, 0));
  tally.start_trajectory();
  m.validity = tally.metrics();
  return m;
}

std::string metrics_error(const Json& json) {
  try {
    rollout_metrics_from_json(json, "RUN/rollout/metrics.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(ValidityTally, RoundTripsThroughMetricsJson) {
  const RolloutMetrics m = with_validity();
  const Json written = Json::parse(to_json(m).dump());
  ASSERT_TRUE(written.contains("validity"));
  EXPECT_TRUE(written["validity"]["model"]["overlap"]["per_trajectory"][1].is_null());
  const RolloutMetrics back = rollout_metrics_from_json(written, "metrics.json");
  ASSERT_TRUE(back.validity && back.validity->model.overlap);
  EXPECT_EQ(back.validity->model.overlap->max, m.validity->model.overlap->max);
  EXPECT_EQ(back.validity->truth.nodes_outside_walls->per_step,
            m.validity->truth.nodes_outside_walls->per_step);
  EXPECT_TRUE(std::isnan(back.validity->model.overlap->per_trajectory[1]));
  EXPECT_EQ(Json::parse(to_json(back).dump()), written);
  // Files written before the measures existed read, without them.
  Json older = written;
  older.erase("validity");
  EXPECT_FALSE(rollout_metrics_from_json(older, "metrics.json").validity.has_value());
  // A scene without walls writes no wall curves, and reads back the same.
  RolloutMetrics no_walls = m;
  no_walls.validity->model.outside_walls.reset();
  no_walls.validity->model.nodes_outside_walls.reset();
  no_walls.validity->truth.outside_walls.reset();
  no_walls.validity->truth.nodes_outside_walls.reset();
  const Json nw = Json::parse(to_json(no_walls).dump());
  EXPECT_FALSE(nw["validity"]["model"].contains("outside_walls"));
  EXPECT_FALSE(rollout_metrics_from_json(nw, "m.json").validity->truth.outside_walls.has_value());
  // Eulerian files have none.
  RolloutMetrics e = m;
  e.eulerian = true;
  EXPECT_FALSE(to_json(e).contains("validity"));
}

TEST(ValidityTally, ReaderIsStrict) {
  const Json good = to_json(with_validity());
  EXPECT_EQ(metrics_error(good), "no error");
  Json unknown = good;
  unknown["validity"]["model"]["penetration"] = unknown["validity"]["model"]["overlap"];
  EXPECT_NE(metrics_error(unknown).find("validity.model"), std::string::npos)
      << metrics_error(unknown);
  Json no_truth = good;
  no_truth["validity"].erase("truth");
  EXPECT_NE(metrics_error(no_truth).find("validity.truth"), std::string::npos)
      << metrics_error(no_truth);
  Json no_max = good;
  no_max["validity"]["truth"]["overlap"].erase("max");
  EXPECT_NE(metrics_error(no_max).find("validity.truth.overlap.max"), std::string::npos)
      << metrics_error(no_max);
  Json typed = good;
  typed["validity"]["model"]["outside_walls"]["per_step"] = "far";
  EXPECT_NE(metrics_error(typed).find("validity.model.outside_walls.per_step"), std::string::npos)
      << metrics_error(typed);
}

}  // namespace
}  // namespace bsms
