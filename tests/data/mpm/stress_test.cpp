// Solver stress tests: each either runs with a finite state or stops with a NumericalError that
// names the step, the particle and the cause. No NaN may survive a step.
#include <gtest/gtest.h>

#include <string>

#include "core/error.hpp"
#include "data/mpm/scene_builder.hpp"
#include "mpm_test_util.hpp"

namespace bsms::mpm {
namespace {

using testing::make_solver;
using testing::scene_path;

bool state_finite(const MpmSolver<2>& solver) {
  const auto& p = solver.particles();
  for (int32_t i = 0; i < p.size(); ++i)
    if (!p.x[i].allFinite() || !p.v[i].allFinite() || !p.F[i].allFinite()) return false;
  return true;
}

// Runs to the end; returns the NumericalError message, or "" when the run finished (finite).
std::string run_or_error(MpmSolver<2>& solver, double end_time) {
  try {
    solver.advance_to(end_time);
  } catch (const NumericalError& e) {
    return e.what();
  }
  EXPECT_TRUE(state_finite(solver));
  return "";
}

void expect_named(const std::string& message) {
  EXPECT_NE(message.find("step "), std::string::npos) << message;
  EXPECT_NE(message.find("particle "), std::string::npos) << message;
}

const std::vector<std::string> kCoarseSquare = {"background.element_size=0.05",
                                                "solver.end_time=0.2"};

TEST(SolverStress, ParticleLeavingTheMeshStopsWithItsName) {
  auto sets = kCoarseSquare;
  sets.push_back("bodies.0.velocity={\"type\": \"uniform\", \"value\": [5.0, 0.0]}");
  MpmSolver<2> solver = make_solver(load_scene(scene_path("rotating_square.json"), sets));
  const std::string message = run_or_error(solver, 0.2);
  ASSERT_FALSE(message.empty());
  expect_named(message);
  EXPECT_NE(message.find("left the background mesh"), std::string::npos) << message;
}

TEST(SolverStress, TimeStepFarAboveCflStopsOrStaysFinite) {
  auto sets = kCoarseSquare;
  sets.push_back("solver.dt=0.005");  // ~40x the CFL step
  MpmSolver<2> solver = make_solver(load_scene(scene_path("rotating_square.json"), sets));
  const std::string message = run_or_error(solver, 0.2);
  if (!message.empty()) expect_named(message);
  std::printf("dt 40x CFL: %s\n", message.empty() ? "finished, finite" : message.c_str());
}

TEST(SolverStress, HighSpeedImpactOnAWallStopsOrStaysFinite) {
  auto sets = kCoarseSquare;
  sets.push_back("bodies.0.velocity={\"type\": \"uniform\", \"value\": [-60.0, 0.0]}");
  sets.push_back("boundaries=[{\"group\": \"left\", \"type\": \"slip\"}]");
  sets.push_back("solver.end_time=0.02");
  MpmSolver<2> solver = make_solver(load_scene(scene_path("rotating_square.json"), sets));
  const std::string message = run_or_error(solver, 0.02);
  if (!message.empty()) expect_named(message);
  std::printf("impact at 60 m/s: %s\n", message.empty() ? "finished, finite" : message.c_str());
}

TEST(SolverStress, SliverElementsStopOrStayFinite) {
  // A structured mesh with one row of nodes squeezed onto its neighbours: slivers of aspect ~1e-3.
  const int n = 11;
  RowMatrixXd points(n * n, 2);
  RowMatrixXi64 cells(2 * (n - 1) * (n - 1), 3);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) points.row(j * n + i) << 0.1 * i, j == 5 ? 0.4001 : 0.1 * j;
  int c = 0;
  for (int j = 0; j + 1 < n; ++j)
    for (int i = 0; i + 1 < n; ++i) {
      const int a = j * n + i;
      cells.row(c++) << a, a + 1, a + n + 1;
      cells.row(c++) << a, a + n + 1, a + n;
    }
  BackgroundMesh<2> bg = make_background<2>(make_mesh(2, points, cells), true, "slivers");
  Particles<2> particles;
  particles.resize(64);
  for (int k = 0; k < 64; ++k) {
    particles.x[k] = Vec<2>(0.3 + 0.02 * (k % 8), 0.2 + 0.02 * (k / 8));
    particles.v[k] = Vec<2>(0.0, 1.0);
    particles.mass[k] = particles.volume0[k] = 4e-4;
  }
  Material material;
  material.model = MaterialModel::kNeoHookean;
  material.youngs_modulus = 1e3;
  material.poisson_ratio = 0.3;
  SolverSettings<2> settings;
  MpmSolver<2> solver(std::move(bg), {material}, std::move(particles), {}, settings);
  const std::string message = run_or_error(solver, 0.3);  // crosses the sliver row
  if (!message.empty()) expect_named(message);
  std::printf("sliver elements: %s\n", message.empty() ? "finished, finite" : message.c_str());
}

TEST(SolverStress, InvertedInitialStateIsRejected) {
  auto sets = kCoarseSquare;
  Scene scene = load_scene(scene_path("rotating_square.json"), sets);
  BuiltScene<2> b = build_scene<2>(scene);
  b.particles.F[3] = Vec<2>(-1.0, 1.0).asDiagonal();
  EXPECT_THROW(MpmSolver<2>(std::move(b.background), std::move(b.materials), std::move(b.particles),
                            std::move(b.constraints), b.settings),
               NumericalError);
}

}  // namespace
}  // namespace bsms::mpm
