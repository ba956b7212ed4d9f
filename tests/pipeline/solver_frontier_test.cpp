// bsms experiment solver-frontier: the interpolation that reads a solve on other mesh nodes at
// the stored nodes (exact for affine motions, in 2-D and 3-D, inside cells and just outside), the
// --setting syntax and the default settings, the experiment on a small generated dataset (the
// ground-truth re-solve reproduces the stored frames, a coarser solve does not, the references
// are a rollout's), and the report's frontier table and verdicts.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>

#include "core/error.hpp"
#include "data/dataset/dataset.hpp"
#include "data/generate/family.hpp"
#include "data/generate/generator.hpp"
#include "pipeline/experiments/node_interpolation.hpp"
#include "pipeline/experiments/solver_frontier.hpp"
#include "pipeline/report/report.hpp"
#include "pipeline/runs/rollout_metrics.hpp"
#include "pipeline/runs/run_files.hpp"
#include "pipeline/runs/train_log.hpp"
#include "tests/temp_dir.hpp"

// A named namespace: the test target is a unity build, and other files' helpers (fresh_dir, ...)
// share its translation units.
namespace solver_frontier_test {

namespace fs = std::filesystem;
using namespace bsms;

// A path that does not exist yet, in a new folder of this test process.
fs::path fresh_dir(const std::string& name) {
  return bsms::testing::unique_temp_dir("solver_frontier") / name;
}

std::string read_text(const fs::path& file) {
  std::ifstream in(file);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// A structured simplex mesh of the unit square (2-D: each square cut into 2 triangles) or cube
// (3-D: each cube into the 6 tetrahedra of the Kuhn split), n cells a side, shifted by `offset`
// along x, as body `body`; appended to x, cells and bodies.
void add_box(int dim, int n, double offset, int32_t body, std::vector<float>& x,
             std::vector<int32_t>& cells, std::vector<int32_t>& bodies) {
  const int32_t first = static_cast<int32_t>(bodies.size());
  const int m = n + 1;
  const int nz = dim == 3 ? m : 1;
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i) {
        x.push_back(static_cast<float>(offset + static_cast<double>(i) / n));
        x.push_back(static_cast<float>(static_cast<double>(j) / n));
        if (dim == 3) x.push_back(static_cast<float>(static_cast<double>(k) / n));
        bodies.push_back(body);
      }
  const auto id = [&](int i, int j, int k) { return first + (k * m + j) * m + i; };
  for (int k = 0; k < (dim == 3 ? n : 1); ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        if (dim == 2) {
          cells.insert(cells.end(), {id(i, j, 0), id(i + 1, j, 0), id(i + 1, j + 1, 0)});
          cells.insert(cells.end(), {id(i, j, 0), id(i + 1, j + 1, 0), id(i, j + 1, 0)});
          continue;
        }
        // Kuhn: the 6 monotone paths from corner 000 to 111.
        const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
        for (const auto& p : perms) {
          int c[3] = {0, 0, 0};
          cells.push_back(id(i, j, k));
          for (int step : p) {
            c[step] = 1;
            cells.push_back(id(i + c[0], j + c[1], k + c[2]));
          }
        }
      }
}

// Random points of two boxes' bodies, some up to `margin` outside them.
void add_points(int dim, int count, double margin, std::mt19937_64& rng, std::vector<float>& p,
                std::vector<int32_t>& bodies) {
  std::uniform_real_distribution<double> u(-margin, 1.0 + margin);
  for (int q = 0; q < count; ++q) {
    const int32_t body = q % 2;
    p.push_back(static_cast<float>(2.0 * body + u(rng)));
    for (int a = 1; a < dim; ++a) p.push_back(static_cast<float>(u(rng)));
    bodies.push_back(body);
  }
}

// Each body moved by its own map; `affine` false adds a quadratic part.
std::vector<float> moved(const std::vector<float>& x, const std::vector<int32_t>& bodies, int dim,
                         bool affine) {
  std::vector<float> out(x.size());
  for (size_t i = 0; i < bodies.size(); ++i) {
    const double s = bodies[i] == 0 ? 1.0 : -0.7;
    double p[3] = {0, 0, 0};
    for (int a = 0; a < dim; ++a) p[a] = x[i * dim + a];
    double y[3];
    y[0] = 0.3 + 1.1 * p[0] - 0.4 * s * p[1] + (dim == 3 ? 0.2 * p[2] : 0.0);
    y[1] = -0.2 + 0.5 * s * p[0] + 0.9 * p[1] + (dim == 3 ? -0.1 * p[2] : 0.0);
    y[2] = 0.1 - 0.3 * p[0] + 0.25 * p[1] + 1.2 * s * p[2];
    if (!affine) y[0] += 0.5 * p[1] * p[1];
    for (int a = 0; a < dim; ++a) out[i * dim + a] = static_cast<float>(y[a]);
  }
  return out;
}

TEST(NodeInterpolation, ReproducesAffineMotionsInsideAndJustOutside) {
  std::mt19937_64 rng(3);
  for (int dim : {2, 3}) {
    SCOPED_TRACE("dim " + std::to_string(dim));
    std::vector<float> x, points;
    std::vector<int32_t> cells, bodies, point_bodies;
    add_box(dim, dim == 2 ? 6 : 3, 0.0, 0, x, cells, bodies);
    add_box(dim, dim == 2 ? 4 : 2, 2.0, 1, x, cells, bodies);
    add_points(dim, 400, 0.04, rng, points, point_bodies);
    const NodeInterpolation map = locate_points(x, bodies, cells, points, point_bodies, dim);
    EXPECT_GT(map.outside, 0);  // the margin puts some points outside
    EXPECT_LT(map.outside, 400);
    EXPECT_LE(map.farthest_outside, 0.04 * std::sqrt(dim) + 1e-6);
    // Every weight set sums to 1 and uses nodes of the point's own body; a point inside its body
    // has no negative weight.
    const int k = dim + 1;
    for (int64_t q = 0; q < map.points; ++q) {
      double sum = 0, lowest = 1;
      for (int j = 0; j < k; ++j) {
        sum += map.weights[q * k + j];
        lowest = std::min(lowest, map.weights[q * k + j]);
        EXPECT_EQ(bodies[map.corners[q * k + j]], point_bodies[q]);
      }
      EXPECT_NEAR(sum, 1.0, 1e-12);
      bool inside = true;
      for (int a = 0; a < dim; ++a) {
        const double v = points[q * dim + a] - (a == 0 ? 2.0 * point_bodies[q] : 0.0);
        inside = inside && v >= 0 && v <= 1;
      }
      if (inside) {
        EXPECT_GE(lowest, -1e-6);
      }
    }
    // Affine motion of the source: the points move by the same map, inside and outside.
    std::vector<float> out(points.size());
    interpolate_points(map, moved(x, bodies, dim, true).data(), out.data());
    const std::vector<float> expected = moved(points, point_bodies, dim, true);
    double worst = 0;
    for (size_t i = 0; i < out.size(); ++i)
      worst = std::max(worst, std::abs(static_cast<double>(out[i]) - expected[i]));
    EXPECT_LT(worst, 1e-6);
    // The check can fail: a motion with a quadratic part is not reproduced between nodes.
    interpolate_points(map, moved(x, bodies, dim, false).data(), out.data());
    const std::vector<float> curved = moved(points, point_bodies, dim, false);
    worst = 0;
    for (size_t i = 0; i < out.size(); ++i)
      worst = std::max(worst, std::abs(static_cast<double>(out[i]) - curved[i]));
    EXPECT_GT(worst, 1e-3);
  }
  // A point of a body the source lacks.
  std::vector<float> x, points = {0.5f, 0.5f};
  std::vector<int32_t> cells, bodies, point_bodies = {7};
  add_box(2, 2, 0.0, 0, x, cells, bodies);
  EXPECT_THROW(locate_points(x, bodies, cells, points, point_bodies, 2), InputError);
}

TEST(SolverFrontier, SettingsParseAndDefaultsScaleTheFamilysKnobs) {
  const SolverSetting s =
      parse_solver_setting("g2=scene.gravity=[0, -2],scene.solver.cfl=0.5,sample.speed=[0.1,0.2]");
  EXPECT_EQ(s.name, "g2");
  ASSERT_EQ(s.assignments.size(), 3u);
  EXPECT_EQ(s.assignments[0], "scene.gravity=[0, -2]");
  EXPECT_EQ(s.assignments[2], "sample.speed=[0.1,0.2]");
  for (const char* bad : {"scene.solver.cfl=0.5", "=scene.solver.cfl=0.5", "a b=scene.solver.cfl=1",
                          "x=solver.cfl=0.5", "x=scene.solver.cfl=", "x=frames=3",
                          "ground_truth=scene.solver.cfl=0.5", "x=scene.solver.cfl=0.5,"})
    EXPECT_THROW(parse_solver_setting(bad), InputError) << bad;

  const std::string families = std::string(BSMS_SOURCE_DIR) + "/configs/families/";
  std::vector<std::string> notes;
  const auto disks = default_solver_settings(load_json_file(families + "disks2d.json"),
                                             families + "disks2d.json", notes);
  ASSERT_EQ(disks.size(), 6u);
  EXPECT_EQ(disks[0].name, "background_x1.5");
  EXPECT_EQ(disks[0].assignments, std::vector<std::string>{"scene.background.element_size=0.06"});
  EXPECT_EQ(disks[1].assignments, std::vector<std::string>{"scene.background.element_size=0.08"});
  EXPECT_EQ(disks[2].assignments, std::vector<std::string>{"scene.solver.cfl=0.6"});
  EXPECT_EQ(disks[3].assignments, std::vector<std::string>{"scene.solver.cfl=0.9"});
  EXPECT_EQ(disks[4].name, "spacing_x1.5");
  EXPECT_EQ(disks[4].assignments, std::vector<std::string>{"sample.spacing=0.0375"});
  EXPECT_EQ(disks[5].name, kAnotherMesh);  // the same resolution, another mesh
  EXPECT_EQ(disks[5].assignments,
            std::vector<std::string>{"scene.background.element_size=0.04056"});
  EXPECT_TRUE(notes.empty());
  // Every key ending in _spacing; a CFL number capped at 1 once, the second multiple dropped.
  Json press = load_json_file(families + "press2d.json");
  press["scene"]["solver"]["cfl"] = 0.6;
  const auto p = default_solver_settings(press, families + "press2d.json", notes);
  ASSERT_EQ(p.size(), 5u);
  EXPECT_EQ(p[2].name, "cfl_x2");
  EXPECT_EQ(p[2].assignments, std::vector<std::string>{"scene.solver.cfl=1"});
  EXPECT_EQ(p[3].assignments.size(), 2u);
  EXPECT_NE(p[3].assignments[0].find("_spacing=0.0375"), std::string::npos);
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("cfl_x2: capped at CFL 1"), std::string::npos) << notes[0];
  // The bodies family's node-count bounds shrink with the coarser spacing (1.5^3 in 3-D), so the
  // re-solve draws the same bodies: the family still parses and draws them.
  notes.clear();
  Json bodies = load_json_file(families + "bodies3d.json");
  bodies["sample"]["nodes"] = Json::array({675, 2700});
  const auto b = default_solver_settings(bodies, families + "bodies3d.json", notes);
  ASSERT_GE(b.size(), 2u);
  const SolverSetting& b_spacing = b[b.size() - 2];
  ASSERT_EQ(b_spacing.name, "spacing_x1.5");
  EXPECT_EQ(b_spacing.assignments,
            (std::vector<std::string>{"sample.spacing=0.0525", "sample.nodes=[200,800]"}));
  EXPECT_EQ(b.back().assignments,
            std::vector<std::string>{"scene.background.element_size=0.07098"});
}

// RMSE-all of constant velocity over predicted frames 2 .. F-1, computed here from the file.
double constant_velocity_rmse(const Dataset& d, int64_t count) {
  double sum = 0;
  int64_t steps = 0;
  for (int64_t t = 0; t < count; ++t) {
    const TrajectoryMesh& mesh = d.mesh(t);
    const int64_t f_count = d.num_frames(t), n = mesh.num_nodes();
    const std::vector<float> x = d.read(t, "world_pos", 0, f_count);
    for (int64_t f = 2; f < f_count; ++f) {
      double mse = 0;
      for (int64_t i = 0; i < n; ++i)
        for (int a = 0; a < 2; ++a) {
          const double x0 = x[i * 2 + a], x1 = x[(n + i) * 2 + a], xf = x[(f * n + i) * 2 + a];
          const double cv = mesh.node_type[i] == 0 ? x1 + (f - 1) * (x1 - x0) : xf;
          mse += (cv - xf) * (cv - xf);
        }
      sum += mse / static_cast<double>(n * 2);
      ++steps;
    }
  }
  return std::sqrt(sum / static_cast<double>(steps));
}

TEST(SolverFrontier, GroundTruthReproducesTheDataAndCheaperSettingsDoNot) {
  const generate::FamilyConfig family =
      generate::load_family(std::string(BSMS_SOURCE_DIR) + "/configs/families/disks2d.json",
                            {"frames=10", "sample.count=[2, 2]", "sample.spacing=0.04",
                             "scene.background.element_size=0.06"});
  generate::GenerateOptions g;
  g.trajectories = 3;
  g.split = {0, 0, 1};
  g.seed = 11;
  g.threads = 2;
  g.out_dir = fresh_dir("data").string();
  generate::generate_dataset(family, g);

  SolverFrontierOptions o;
  o.data = g.out_dir;
  o.out = fresh_dir("out").string();
  o.threads = 2;
  o.quiet = true;
  // A bare name picks that default setting: another_mesh, the same resolution on a mesh gmsh
  // lays out otherwise.
  o.settings = {"coarse=scene.background.element_size=0.09", "sparse=sample.spacing=0.06",
                kAnotherMesh};
  const SolverFrontier r = solver_frontier_experiment(o);
  EXPECT_EQ(r.trajectories, 3);
  EXPECT_EQ(r.frames, 10);
  EXPECT_EQ(r.family, "disks");
  const FrontierSetting& truth = r.ground_truth;
  EXPECT_LT(truth.rmse_all, 1e-5);
  EXPECT_LT(truth.max_abs_diff_m, 1e-5);
  EXPECT_FALSE(truth.interpolated);
  EXPECT_GT(truth.ms_per_frame, 0);
  EXPECT_DOUBLE_EQ(truth.speedup_vs_ground_truth, 1.0);
  ASSERT_TRUE(r.stored_ms_per_frame);  // bsms generate's timing of the same solves
  EXPECT_GT(*r.stored_ms_per_frame, 0);
  ASSERT_EQ(r.settings.size(), 3u);
  const FrontierSetting &coarse = r.settings[0], &sparse = r.settings[1], &remeshed = r.settings[2];
  EXPECT_EQ(coarse.assignments, std::vector<std::string>{"scene.background.element_size=0.09"});
  EXPECT_FALSE(coarse.interpolated);
  EXPECT_TRUE(sparse.interpolated);  // other particles: read at the stored nodes
  EXPECT_EQ(remeshed.assignments,
            std::vector<std::string>{"scene.background.element_size=0.06084"});
  for (const FrontierSetting* s : {&coarse, &sparse, &remeshed}) {
    EXPECT_EQ(s->unstable, 0);
    EXPECT_TRUE(std::isfinite(s->rmse_all) && s->rmse_all > 1e-6) << s->name;
    EXPECT_TRUE(std::isfinite(s->ms_per_frame) && s->ms_per_frame > 0) << s->name;
    ASSERT_EQ(s->per_trajectory.size(), 3u);
    // RMSE-all is the step-weighted RMS of the trajectories' RMSEs, as a rollout's.
    double sq = 0, steps = 0;
    for (const auto& t : s->per_trajectory) {
      EXPECT_EQ(t.steps, 8);
      sq += t.rmse_all * t.rmse_all * t.steps;
      steps += t.steps;
    }
    EXPECT_NEAR(s->rmse_all, std::sqrt(sq / steps), 1e-12);
  }
  // Constant velocity as bsms rollout extrapolates it, over the same frames.
  const Dataset test = Dataset::open_split(g.out_dir, "test");
  // (The rollout extrapolates in float, this check in double.)
  EXPECT_NEAR(r.rmse_all_constant_velocity, constant_velocity_rmse(test, 3),
              1e-3 * r.rmse_all_constant_velocity + 1e-8);
  EXPECT_NEAR(coarse.rmse_all_over_constant_velocity,
              coarse.rmse_all / r.rmse_all_constant_velocity, 1e-12);

  // The file reads back as written; the table is there.
  const SolverFrontier back = read_solver_frontier(o.out);
  EXPECT_EQ(to_json(back), to_json(r));
  const std::string md = read_text(fs::path(o.out) / "solver_frontier.md");
  EXPECT_NE(md.find("| sparse (interpolated) |"), std::string::npos) << md;
  // Another mesh of the same size changes the truth, and the file says what that measures.
  EXPECT_EQ(another_mesh_setting(r), &r.settings[2]);
  EXPECT_NE(md.find(another_mesh_paragraph(r)), std::string::npos) << md;
  EXPECT_NE(md.find("is that part's size"), std::string::npos) << md;
  // A strict reader: an unknown key, or a setting short of trajectories, names the file.
  Json damaged = to_json(r);
  damaged["settings"][0]["colour"] = "red";
  EXPECT_THROW(solver_frontier_from_json(damaged, "m.json"), InputError);
  damaged = to_json(r);
  damaged["settings"][1]["per_trajectory"].erase(0);
  EXPECT_THROW(solver_frontier_from_json(damaged, "m.json"), InputError);

  // An unknown key is refused before any solve, naming the key.
  o.settings = {"typo=scene.solver.cfll=0.5"};
  o.out = fresh_dir("typo").string();
  try {
    solver_frontier_experiment(o);
    ADD_FAILURE() << "an unknown key was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("solver.cfll"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(o.out));
  // So is a bare name that is not a default setting, naming the ones there are.
  o.settings = {"cfl_x9"};
  try {
    solver_frontier_experiment(o);
    ADD_FAILURE() << "an unknown default setting was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cfl_x9: not a default setting"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("cfl_x2, cfl_x3, spacing_x1.5, another_mesh"),
              std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(fs::exists(o.out));
}

// A run folder with a rollout metrics file and a two-step training log (what bsms report reads).
std::string fake_run(const fs::path& dir, double ms_per_step, double rmse_all) {
  fs::create_directories(dir / "rollout");
  RolloutMetrics m;
  m.model = "bsms";
  m.split = "test";
  m.data = "elsewhere/test.h5";
  m.num_trajectories = 2;
  m.seeding = "minave";
  FieldRmse all;
  all.fields = {{"world_pos", rmse_all}, {"velocity", 0.1}};
  all.total = rmse_all;
  m.rmse_1 = m.rmse_50 = m.rmse_all = all;
  m.rmse_per_step["world_pos"] = {rmse_all};
  m.rmse_all_constant_velocity = 0.2;
  m.infer_ms_per_step = ms_per_step;
  m.threads = 2;
  write_json_atomic((dir / "rollout" / "metrics.json").string(), to_json(m));
  std::ofstream((dir / "train_log.csv").string())
      << kTrainLogHeader << "\n1,0.5,0.3,,,0.001\n2,1.0,0.2,0.25,1.0,0.001\n";
  return dir.string();
}

FrontierSetting fake_setting(const std::string& name, double ms, double rmse, int64_t unstable) {
  FrontierSetting s;
  s.name = name;
  if (name != "ground_truth") s.assignments = {"scene.solver.cfl=0.6"};
  s.ms_per_frame = ms;
  s.speedup_vs_ground_truth = 8.0 / ms;
  s.rmse_all = rmse;
  s.rmse_all_over_constant_velocity = rmse / 0.2;
  s.max_abs_diff_m = rmse * 3;
  s.unstable = unstable;
  for (int64_t t = 0; t < 2; ++t) {
    FrontierTrajectory tr;
    tr.trajectory = t;
    tr.index = 10 + t;
    tr.unstable = t < unstable;
    if (tr.unstable) tr.message = "non-finite state";
    tr.ms_per_frame = tr.unstable ? std::nan("") : ms;
    tr.rmse_all = tr.unstable ? std::nan("") : rmse;
    tr.rmse_all_constant_velocity = 0.2;
    tr.steps = tr.unstable ? 0 : 48;
    s.per_trajectory.push_back(tr);
  }
  return s;
}

TEST(Report, ThesisTableSetsTheModelsSideBySidePerDataset) {
  const fs::path dir = fresh_dir("thesis_table");
  auto run = [&](const std::string& name, const std::string& model, const std::string& data,
                 double scale) {
    const std::string path = fake_run(dir / name, 1.0, 0.02);
    RolloutMetrics m = read_rollout_metrics((fs::path(path) / "rollout" / "metrics.json").string());
    m.model = model;
    m.data = data;
    for (const auto& [h, v] : std::vector<std::pair<std::string, double>>{
             {"1", 1e-3}, {"10", 2e-3}, {"50", 5e-3}, {"all", 8e-3}}) {
      FieldRmse f;
      f.fields = {{"world_pos", scale * v}};
      f.total = scale * v;
      m.rmse_trajectory_mean[h] = f;
    }
    write_json_atomic((fs::path(path) / "rollout" / "metrics.json").string(), to_json(m));
    return path;
  };
  ReportRequest request;
  request.runs = {run("b", "bsms", "runs/public/plate/", 1.0),
                  run("m", "mgn", "runs/public/plate", 2.0),
                  run("c", "bsms", "data/cubes/test.h5", 1.0)};
  request.out = (dir / "out").string();
  const std::string text = read_text(write_report(request));
  EXPECT_NE(text.find("| dataset | field | MeshGraphNets RMSE-1 | RMSE-50 | RMSE-all | BSMS-GNN "
                      "RMSE-1 | RMSE-50 | RMSE-all | runs |"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("| plate | world_pos | 2 | 10 | 16 | 1 | 5 | 8 |"), std::string::npos)
      << text;
  EXPECT_NE(text.find("| cubes | world_pos | – | – | – | 1 | 5 | 8 |"), std::string::npos) << text;
}

TEST(SolverFrontier, ReportDrawsTheFrontierAndSaysWhetherASettingBeatsEachRun) {
  const fs::path dir = fresh_dir("report");
  // fast: 1 ms/step, no setting that fast; slow: 20 ms/step, beaten by cheap (4 ms/frame, more
  // accurate) and by the ground truth (8 ms/frame, exact); "shaky" is faster and more accurate
  // still but unstable on one trajectory, so not counted.
  const std::string fast = fake_run(dir / "fast", 1.0, 0.02);
  const std::string slow = fake_run(dir / "slow", 20.0, 0.02);
  SolverFrontier f;
  f.data = "elsewhere/test.h5";
  f.split = "test";
  f.family = "disks";
  f.trajectories = 2;
  f.frames = 50;
  f.threads = 2;
  f.hardware_threads = 2;
  f.wall_s = 3;
  f.rmse_all_constant_velocity = 0.2;
  f.ground_truth = fake_setting("ground_truth", 8.0, 0.0, 0);
  f.settings = {fake_setting("cheap", 4.0, 0.005, 0), fake_setting("shaky", 2.0, 0.001, 1),
                fake_setting("useless", 3.0, 0.5, 0), fake_setting(kAnotherMesh, 9.0, 0.01, 0)};
  fs::create_directories(dir / "frontier");
  write_json_atomic((dir / "frontier" / "metrics.json").string(), to_json(f));

  ReportRequest request;
  request.runs = {fast, slow};
  request.out = (dir / "out").string();
  request.solver_frontier = (dir / "frontier").string();
  const std::string text = read_text(write_report(request));
  EXPECT_NE(text.find("| solver setting | changes | ms/frame | speed-up vs ground truth | "
                      "RMSE-all | × constant velocity | unstable |"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("| cheap | `scene.solver.cfl=0.6` | 4.00 | 2.00× | 5.00e-03 | 0.025 | 0 |"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("| ground_truth | as stored | 8.00 | 1.00× | 0.00e+00 | 0 | 0 |"),
            std::string::npos)
      << text;
  // The nearest alternative is named: cheap costs 4 model steps at a quarter of the error.
  EXPECT_NE(text.find("- fast (1.00 ms/step, RMSE-all 2.00e-02 m): no cheaper solver setting is "
                      "both as fast and as accurate. The cheapest more accurate one, cheap, costs "
                      "4.00× the model's time per frame at 0.25× its RMSE-all. Faster than that "
                      "and more accurate, but unstable: shaky (lost 1 of 2 solves). Its "
                      "RMSE-all is 2× another_mesh's."),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("- slow (20.00 ms/step, RMSE-all 2.00e-02 m): beaten by solver setting "
                      "ground_truth (8.00 ms/frame, RMSE-all 0.00e+00 m); also by cheap, "
                      "another_mesh. Its RMSE-all is 2× another_mesh's."),
            std::string::npos)
      << text;
  // What another mesh of the same size measures is said once, under the table.
  EXPECT_NE(text.find("another_mesh's 0.05× constant velocity is that part's size"),
            std::string::npos)
      << text;
  // An another_mesh that reproduces the data did not remesh, and is said not to measure anything.
  SolverFrontier same = f;
  same.settings.back().rmse_all = 0;
  EXPECT_NE(another_mesh_paragraph(same).find("left the mesh as it was"), std::string::npos);
  // Re-solves lost on the other mesh are counted; one with no stable solve says nothing.
  same.settings.back().rmse_all = 0.01;
  same.settings.back().unstable = 1;
  EXPECT_NE(another_mesh_paragraph(same).find("1 of 2 re-solves were unstable"), std::string::npos)
      << another_mesh_paragraph(same);
  same.settings.back().rmse_all = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(another_mesh_setting(same), nullptr);
  EXPECT_EQ(another_mesh_paragraph(same), "");
  // The frontier is a second data block of the speed plot's data, unstable points marked.
  const std::string speed = read_text(dir / "out" / "plots" / "speed.dat");
  const size_t block = speed.find("\n\n\n");
  ASSERT_NE(block, std::string::npos) << speed;
  EXPECT_NE(speed.find("\"cheap\" 4.000000 0.00500000", block), std::string::npos) << speed;
  EXPECT_NE(speed.find("\"shaky (1 unstable)\"", block), std::string::npos) << speed;
  EXPECT_NE(speed.find("\"ground_truth\" 8.000000", block), std::string::npos) << speed;
  const std::string script = read_text(dir / "out" / "plots" / "speed_vs_error.gp");
  EXPECT_NE(script.find("UMLS-MPM at cheaper settings"), std::string::npos) << script;
  // A missing frontier is named.
  request.solver_frontier = (dir / "nowhere").string();
  try {
    write_report(request);
    ADD_FAILURE() << "a missing frontier was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("nowhere"), std::string::npos) << e.what();
  }
}

}  // namespace solver_frontier_test
