// Solver validation against the papers: the vibrating bar's analytic centre of mass, the APIC
// rotating square's momentum conservation, the cantilever under mesh rotation, and the
// cell-crossing comparison with linear FEM kernels and UMLS without η.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "core/error.hpp"
#include "core/runtime.hpp"
#include "data/mpm/scene_config.hpp"
#include "mpm_test_util.hpp"

namespace bsms::mpm {
namespace {

using testing::make_solver;
using testing::scene_path;

constexpr double kPi = 3.14159265358979323846;

struct BarErrors {
  double com = 0.0;     // centre-of-mass RMSE / its amplitude v0 / (β L ω)
  double stress = 0.0;  // stress RMSE at the particle nearest x = 12.75 m / its amplitude
};

// The vibrating bar against its analytic solution: x_cm(t) = L/2 + v0/(β L ω) sin(ω t) and, the
// model being linear in the reference frame, σ(X, t) = E v0 β / ω cos(β X) sin(ω t) (von Mises =
// |σ| in uniaxial stress). Sampled at `frames` equal intervals of end_time.
BarErrors bar_errors(const std::vector<std::string>& overrides, int frames = 100) {
  const Scene scene = load_scene(scene_path("vibrating_bar.json"), overrides);
  MpmSolver<2> solver = make_solver(scene);
  const double L = 25.0, v0 = 0.75, E = 100.0, rho = 1.0;
  const double beta = kPi / (2.0 * L), omega = beta * std::sqrt(E / rho);
  const double amplitude = v0 / (beta * L * omega);
  int32_t probe = 0;
  const auto& p = solver.particles();
  for (int32_t i = 0; i < p.size(); ++i)
    if ((p.x[i] - Vec<2>(12.75, 0.5)).norm() < (p.x[probe] - Vec<2>(12.75, 0.5)).norm()) probe = i;
  const double stress_amplitude = E * v0 * beta / omega * std::cos(beta * p.x[probe][0]);
  double com_sum = 0.0, stress_sum = 0.0;
  for (int k = 1; k <= frames; ++k) {
    const double t = scene.solver.end_time * k / frames;
    solver.advance_to(t);
    double m = 0.0, mx = 0.0;
    for (int32_t i = 0; i < p.size(); ++i) {
      m += p.mass[i];
      mx += p.mass[i] * p.x[i][0];
    }
    const double err = mx / m - (0.5 * L + amplitude * std::sin(omega * t));
    com_sum += err * err;
    const double stress_err =
        solver.von_mises_stress()[probe] - std::abs(stress_amplitude * std::sin(omega * t));
    stress_sum += stress_err * stress_err;
  }
  return {std::sqrt(com_sum / frames) / amplitude,
          std::sqrt(stress_sum / frames) / stress_amplitude};
}

double bar_com_error(const std::vector<std::string>& overrides) {
  return bar_errors(overrides).com;
}

TEST(VibratingBar, CentreOfMassMatchesAnalyticSolution) {
  const double error = bar_com_error({});
  std::printf(
      "vibrating bar (UMLS, structured 0.25 m elements, one 10 s period): centre-of-mass RMSE %.3f "
      "%% of "
      "amplitude\n",
      100.0 * error);
  EXPECT_LT(error, 0.00554);  // the paper's figure
}

TEST(VibratingBar, CellCrossingErrorOfLinearFemAndUmlsWithoutEta) {
  // The probe particle crosses cells all the time (paper Fig. 10a): its stress exposes the
  // cell-crossing error; linear FEM kernels may even invert particles.
  const BarErrors umls = bar_errors({});
  const BarErrors no_eta = bar_errors({"solver.kernel=umls_no_eta"});
  const BarErrors bspline = bar_errors({"solver.kernel=bspline"});
  std::string fem = "stopped";
  try {
    const BarErrors e = bar_errors({"solver.kernel=linear_fem"});
    fem = std::to_string(100 * e.com) + " % / " + std::to_string(100 * e.stress) + " %";
    EXPECT_GT(e.stress, 3.0 * umls.stress);
  } catch (const NumericalError& e) {
    fem = std::string("stopped: ") + e.what();
    // The stop names the step, the particle and the cause.
    EXPECT_NE(fem.find("step"), std::string::npos) << fem;
    EXPECT_NE(fem.find("particle"), std::string::npos) << fem;
    EXPECT_NE(fem.find("inverted"), std::string::npos) << fem;
  }
  std::printf(
      "vibrating bar, centre-of-mass / probe-stress RMSE: umls %.3f %% / %.3f %%, umls_no_eta %.3f "
      "%% / "
      "%.3f %%, bspline lattice %.3f %% / %.3f %%, linear_fem %s\n",
      100 * umls.com, 100 * umls.stress, 100 * no_eta.com, 100 * no_eta.stress, 100 * bspline.com,
      100 * bspline.stress, fem.c_str());
  EXPECT_LT(umls.stress, 0.05);
  // Measured: centre of mass / stress 0.536 / 0.697 % (UMLS), 0.510 / 0.592 % (no eta),
  // 0.461 / 0.641 % (B-spline lattice). On this bar the eta term is within noise of UMLS (its
  // benefit shows in the kernel-level jump test), and the smooth lattice kernel is as accurate:
  // all three stay within 1.5x of each other, far below linear FEM.
  for (const BarErrors* e : {&no_eta, &bspline}) {
    EXPECT_LT(e->com, 1.5 * umls.com);
    EXPECT_GT(e->com, umls.com / 1.5);
    EXPECT_LT(e->stress, 1.5 * umls.stress);
    EXPECT_GT(e->stress, umls.stress / 1.5);
  }
}

// Total linear and angular momentum (APIC affine terms included) of the free rotating square.
double kinetic_energy(const MpmSolver<2>& solver) {
  double e = 0.0;
  const auto& p = solver.particles();
  for (int32_t i = 0; i < p.size(); ++i) e += 0.5 * p.mass[i] * p.v[i].squaredNorm();
  return e;
}

// Kelvin–Voigt viscosity on the vibrating bar (a coarser bar, same mode): in uniaxial strain the
// stress gains 2η ∂v/∂x, so the mode decays with damping ratio ζ = η ω / E and after half a
// period (velocities back at their peak) the kinetic energy is exp(−2π ζ) of the undamped run's.
TEST(Viscosity, DampsTheBarsModeAtTheKelvinVoigtRate) {
  const double E = 100.0, L = 25.0, eta = 5.0;
  const double omega = kPi / (2.0 * L) * std::sqrt(E / 1.0);
  const double half_period = kPi / omega;
  auto energy_after_half_period = [&](double viscosity) {
    const Scene scene = load_scene(
        scene_path("vibrating_bar.json"),
        {"bodies.0.spacing=0.125", "bodies.0.material.viscosity=" + std::to_string(viscosity)});
    MpmSolver<2> solver = make_solver(scene);
    const double e0 = kinetic_energy(solver);
    solver.advance_to(half_period);
    return kinetic_energy(solver) / e0;
  };
  const double undamped = energy_after_half_period(0.0);
  const double damped = energy_after_half_period(eta);
  const double expected = std::exp(-2.0 * kPi * eta * omega / E);
  std::printf(
      "vibrating bar, eta %.1f Pa s: kinetic energy after half a period %.4f of the "
      "undamped run's (Kelvin-Voigt: %.4f)\n",
      eta, damped / undamped, expected);
  EXPECT_GT(undamped, 0.95);  // the undamped bar keeps its energy (FLIP, half a period)
  EXPECT_NEAR(std::log(damped / undamped), std::log(expected), 0.25 * -std::log(expected));
}

// A rigid rotation has a skew velocity gradient: viscosity leaves it alone (APIC carries the
// affine field exactly); the bar above shows it damping a deformation at the expected rate.
TEST(Viscosity, SparesARigidRotation) {
  auto run = [](double viscosity) {
    std::vector<std::string> sets = {"background.element_size=0.05", "solver.dt=1e-4",
                                     "solver.end_time=0.1",
                                     "bodies.0.material.viscosity=" + std::to_string(viscosity)};
    sets.push_back(
        "bodies.0.velocity={\"type\": \"rotation\", \"center\": [0.5, 0.5], "
        "\"angular_velocity\": 3.0}");
    const Scene scene = load_scene(scene_path("rotating_square.json"), sets);
    MpmSolver<2> solver = make_solver(scene);
    // Angular momentum, and kinetic plus elastic energy (what viscosity dissipates).
    const Diagnostics<2> d0 = solver.diagnostics();
    solver.advance_to(scene.solver.end_time);
    const Diagnostics<2> d1 = solver.diagnostics();
    return std::pair{d1.angular[0] / d0.angular[0],
                     (d1.kinetic + d1.elastic) / (d0.kinetic + d0.elastic)};
  };
  const auto [l_free, e_free] = run(0.0);
  const auto [l_visc, e_visc] = run(0.5);  // ν = 0.5 m²/s: decays a 0.2 m shear mode in ~0.01 s
  EXPECT_NEAR(l_visc, 1.0, 1e-7);
  EXPECT_NEAR(l_free, 1.0, 1e-7);
  EXPECT_NEAR(e_visc, e_free, 1e-3);
}

TEST(RotatingSquare, ApicConservesLinearAndAngularMomentum) {
  const Scene scene =
      load_scene(scene_path("rotating_square.json"),
                 {"background.element_size=0.05", "solver.dt=1e-4", "solver.end_time=0.2"});
  MpmSolver<2> solver = make_solver(scene);
  const Diagnostics<2> d0 = solver.diagnostics();
  double scale = 0.0;
  for (int32_t p = 0; p < solver.particles().size(); ++p)
    scale += solver.particles().mass[p] * solver.particles().v[p].norm();
  solver.advance_to(scene.solver.end_time);
  const Diagnostics<2> d1 = solver.diagnostics();
  const double linear = (d1.momentum - d0.momentum).norm() / scale;
  const double angular = std::abs(d1.angular[0] - d0.angular[0]) / std::abs(d0.angular[0]);
  std::printf(
      "rotating square, %lld APIC steps: linear momentum drift %.2e (relative to sum m|v|), "
      "angular %.2e\n",
      static_cast<long long>(solver.steps()), linear, angular);
  EXPECT_EQ(solver.steps(), 2000);
  EXPECT_LT(linear, 1e-12);
  EXPECT_LT(angular, 1e-7);
  EXPECT_GT(std::abs(d0.angular[0]), 0.0);
}

// The shipped scene as it is (0.01 m elements, dt 1e-5 s): at step 13943 (frame 14) negative MLS
// weights first leave a node with a negative signed mass. Dropping that node lost momentum (drift
// jumped from 1e-16 to 1.1e-7 linear and 1.4e-6 angular by frame 15, 5.6e-7 / 8.3e-6 at the end);
// both must stay at round-off through and past that event, for the whole run (100,000 steps,
// ~20 s on 2 threads).
TEST(RotatingSquare, ShippedSceneHoldsMomentaThroughNegativeMassNodes) {
  const Scene scene = load_scene(scene_path("rotating_square.json"));
  ASSERT_EQ(scene.solver.transfer, Transfer::kApic);
  MpmSolver<2> solver = make_solver(scene);
  const Diagnostics<2> d0 = solver.diagnostics();
  double scale = 0.0;
  for (int32_t p = 0; p < solver.particles().size(); ++p)
    scale += solver.particles().mass[p] * solver.particles().v[p].norm();
  const int frames = scene.output.frames - 1;
  double linear = 0.0, angular = 0.0;
  int64_t shared_at_frame_13 = 0;
  for (int k = 1; k <= frames; ++k) {
    solver.advance_to(scene.solver.end_time * k / frames);
    const Diagnostics<2> d = solver.diagnostics();
    linear = std::max(linear, (d.momentum - d0.momentum).norm() / scale);
    angular = std::max(angular, std::abs(d.angular[0] - d0.angular[0]) / std::abs(d0.angular[0]));
    if (k == 13) shared_at_frame_13 = solver.shared_node_steps();
  }
  std::printf(
      "rotating square (shipped scene), %lld steps: max linear momentum drift %.2e, angular "
      "%.2e; %lld node-steps with a cancelled mass (first after frame 13: %s)\n",
      static_cast<long long>(solver.steps()), linear, angular,
      static_cast<long long>(solver.shared_node_steps()), shared_at_frame_13 == 0 ? "yes" : "no");
  // Exactly 1000 fixed steps per frame: no sliver steps from the summed time (there were 50).
  EXPECT_EQ(solver.steps(), 100000);
  // The run covers the event (the test can fail): nodes with cancelled mass occur.
  EXPECT_GT(solver.shared_node_steps(), 0);
  EXPECT_LT(linear, 1e-13);
  EXPECT_LT(angular, 1e-12);
}

TEST(RotatingSquare, ThreadCountDoesNotChangeTheResult) {
  // Per-thread scatter buffers: no races, only the summation order of the reduction differs.
  const Scene scene =
      load_scene(scene_path("rotating_square.json"),
                 {"background.element_size=0.05", "solver.dt=1e-4", "solver.end_time=0.02"});
  std::vector<Vec<2>> result[2];
  for (int threads : {1, 2}) {
    set_num_threads(threads);
    MpmSolver<2> solver = make_solver(scene);
    solver.advance_to(scene.solver.end_time);
    result[threads - 1] = solver.particles().x;
  }
  set_num_threads(0);
  double worst = 0.0;
  for (size_t p = 0; p < result[0].size(); ++p)
    worst = std::max(worst, (result[0][p] - result[1][p]).norm());
  EXPECT_LT(worst, 1e-12);
}

TEST(RotatingSquare, FlipDoesNotTrackAffineMomentum) {
  // Without the affine term FLIP loses angular momentum to the grid: the APIC test can fail.
  const Scene scene =
      load_scene(scene_path("rotating_square.json"),
                 {"background.element_size=0.05", "solver.dt=1e-4", "solver.end_time=0.05",
                  "solver.transfer=flip", "solver.flip_ratio=0.0"});
  MpmSolver<2> solver = make_solver(scene);
  const double l0 = solver.diagnostics().angular[0];
  solver.advance_to(scene.solver.end_time);
  EXPECT_GT(std::abs(solver.diagnostics().angular[0] - l0) / std::abs(l0), 1e-4);
}

// Tip y-displacement of the cantilever (particle nearest the right end of the axis), sampled at
// 60 equal intervals of 3 s, on its Delaunay background rotated by `degrees` with the kernel unit h
// held at `kernel_width` (m).
std::vector<double> cantilever_tip(double degrees, double kernel_width) {
  char rotation[64];
  std::snprintf(rotation, sizeof rotation, "background.rotation_deg=%.9f", degrees);
  const Scene scene =
      load_scene(scene_path("cantilever.json"),
                 {rotation, "background.kernel_width=" + std::to_string(kernel_width)});
  MpmSolver<2> solver = make_solver(scene);
  const auto& p = solver.particles();
  int32_t tip = 0;
  for (int32_t i = 0; i < p.size(); ++i)
    if (p.x[i][0] - std::abs(p.x[i][1]) > p.x[tip][0] - std::abs(p.x[tip][1])) tip = i;
  const double y0 = p.x[tip][1];
  std::vector<double> out;
  for (int k = 1; k <= 60; ++k) {
    solver.advance_to(scene.solver.end_time * k / 60);
    out.push_back(p.x[tip][1] - y0);
  }
  return out;
}

TEST(Cantilever, TipDeflectionRobustToMeshRotation) {
  // What this measures, and why not on one mesh per angle. gmsh's Delaunay tessellation is not a
  // continuous function of its input: a further 1e-6 degree of rotation (or an element size
  // changed by 1e-9 relative) gives another mesh, and two such equivalent unrotated meshes give
  // tip histories that differ by 1.8 % RMSE of the peak (median of 12 meshes; up to 6.4 %), mostly
  // through the free nodes next to the clamp. The automatic h (longest edge / 1.45, one outlier
  // edge) adds jumps of up to 6 % in h between meshes. One mesh per angle thus measured one draw
  // of that noise (0.72 / 0.49 / 2.34 %, not monotonic in the angle), which anything that reaches
  // the mesher reshuffles. Here each angle is represented by the mean tip history of kMeshes
  // equivalent meshes (rotation + k 1e-6 degree) with h held at 0.53 m (>= every mesh's longest
  // edge / 1.5): the means differ by the rotation, and the paper's errors bound that difference
  // (measured 0.91 / 1.02 / 3.34 %; single meshes against the unrotated mean: 0.78 to 5.30 %).
  constexpr int kMeshes = 3;
  constexpr double kKernelWidth = 0.53;
  const double paper[4] = {0.0, 0.0127, 0.0218, 0.0472};  // 0 / 15 / 30 / 45 degrees
  std::vector<double> mean[4];
  double single_min = 1.0, single_max = 0.0;  // one mesh per angle against the unrotated mean
  for (int i = 0; i < 4; ++i) {
    mean[i].assign(60, 0.0);
    std::vector<std::vector<double>> tips;
    for (int k = 0; k < kMeshes; ++k) {
      tips.push_back(cantilever_tip(15.0 * i + 1e-6 * k, kKernelWidth));
      for (int t = 0; t < 60; ++t) mean[i][t] += tips.back()[t] / kMeshes;
    }
    if (i == 0) continue;
    double peak = 0.0;
    for (double v : mean[0]) peak = std::max(peak, std::abs(v));
    auto error = [&](const std::vector<double>& tip) {
      double sum = 0.0;
      for (int t = 0; t < 60; ++t) sum += (tip[t] - mean[0][t]) * (tip[t] - mean[0][t]);
      return std::sqrt(sum / 60) / peak;
    };
    for (const auto& tip : tips) {
      single_min = std::min(single_min, error(tip));
      single_max = std::max(single_max, error(tip));
    }
    std::printf(
        "cantilever rotated %.0f deg: tip RMSE of the mean of %d meshes %.2f %% of the peak "
        "deflection %.3f m (paper %.2f %%)\n",
        15.0 * i, kMeshes, 100 * error(mean[i]), peak, 100 * paper[i]);
    EXPECT_LT(error(mean[i]), paper[i]);
  }
  std::printf("single rotated meshes against the unrotated mean: %.2f to %.2f %%\n",
              100 * single_min, 100 * single_max);
  double peak = 0.0;
  for (double v : mean[0]) peak = std::max(peak, std::abs(v));
  EXPECT_GT(peak, 1.2);  // static q L^4 / (8 E I) = 0.74 m, dynamic overshoot about twice that
  EXPECT_LT(peak, 1.8);
}

// The cantilever on its default mesh: oscillates under gravity with its energy kept.
TEST(Cantilever, DeflectsAndKeepsEnergy) {
  const Scene scene = load_scene(scene_path("cantilever.json"), {"solver.end_time=1.0"});
  MpmSolver<2> solver = make_solver(scene);
  double min_y = 0.0;
  int32_t tip = 0;
  const auto& p = solver.particles();
  for (int32_t i = 0; i < p.size(); ++i)
    if (p.x[i][0] - std::abs(p.x[i][1]) > p.x[tip][0] - std::abs(p.x[tip][1])) tip = i;
  const double y0 = p.x[tip][1];
  double max_energy_error = 0.0;
  for (int k = 1; k <= 20; ++k) {
    solver.advance_to(0.05 * k);
    min_y = std::min(min_y, solver.particles().x[tip][1] - y0);
    const Diagnostics<2> d = solver.diagnostics();
    max_energy_error =
        std::max(max_energy_error, std::abs(d.kinetic + d.elastic + d.gravitational));
  }
  // Static deflection q L^4 / (8 E I) = 0.74 m; the dynamic response overshoots to about twice
  // that.
  std::printf("cantilever: tip deflection %.3f m, max |energy change| %.2f J\n", min_y,
              max_energy_error);
  EXPECT_LT(min_y, -1.0);
  EXPECT_GT(min_y, -2.0);
  EXPECT_LT(max_energy_error, 5.0);  // of ~250 J exchanged between potential and elastic energy
}

}  // namespace
}  // namespace bsms::mpm
