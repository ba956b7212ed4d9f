// hencky_j2: Hencky elasticity with J2 return mapping and exponential softening (thesis 2.3.4),
// and the plane-strain slope scene that exercises it.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "data/mpm/material.hpp"
#include "data/mpm/scene_builder.hpp"
#include "data/mpm/simulation.hpp"
#include "data/mpm/solver.hpp"
#include "tests/temp_dir.hpp"

namespace bsms::mpm {
namespace {

const std::string kSlope = std::string(BSMS_SOURCE_DIR) + "/configs/scenes/slope.json";

Material clay(double softening = 5.0) {
  Material m;
  m.model = MaterialModel::kHenckyJ2;
  m.youngs_modulus = 25e6;
  m.poisson_ratio = 0.3;
  m.density = 2150.0;
  m.yield_stress = 40.82e3;
  m.residual_yield_stress = 2.45e3;
  m.softening = softening;
  return m;
}

template <int Dim>
Mat<Dim> rotation(double angle) {
  Mat<Dim> R = Mat<Dim>::Identity();
  R(0, 0) = R(1, 1) = std::cos(angle);
  R(1, 0) = std::sin(angle);
  R(0, 1) = -R(1, 0);
  return R;
}

// von Mises stress of the Kirchhoff stress in the convention of j2_return_map:
// sqrt(3/2) |dev τ| with the deviator over Dim components.
template <int Dim>
double kirchhoff_von_mises(const Material& m, const Mat<Dim>& F) {
  Mat<Dim> sigma;
  double psi;
  elastic_response<Dim>(m, F, sigma, psi);
  const Mat<Dim> tau = sigma * F.determinant();
  const Mat<Dim> dev = tau - tau.trace() / Dim * Mat<Dim>::Identity();
  return std::sqrt(1.5) * dev.norm();
}

TEST(HenckyJ2, BelowYieldIsHenckyElasticity) {
  const Material m = clay();
  const double mu = m.mu(), lambda = m.lambda();
  const Vec<3> s(1.0004, 0.9998, 1.0001);  // deviatoric strain ~3e-4: q ≈ 9 kPa < 40.82 kPa
  const Mat<3> R = rotation<3>(0.7);
  Mat<3> F = R * s.asDiagonal();
  const Mat<3> F0 = F;
  double alpha = 0.0;
  EXPECT_EQ(j2_return_map<3>(m, F, alpha), 0.0);
  EXPECT_EQ(alpha, 0.0);
  EXPECT_TRUE(F == F0);
  Mat<3> sigma;
  double psi;
  elastic_response<3>(m, F, sigma, psi);
  // Closed form for F = R diag(s): σ = R diag(2μ log s_i + λ Σ log s_j) Rᵀ / J.
  const Vec<3> eps = s.array().log().matrix();
  const Vec<3> tau = 2.0 * mu * eps + Vec<3>::Constant(lambda * eps.sum());
  const Mat<3> expected = R * tau.asDiagonal() * R.transpose() / s.prod();
  EXPECT_LT((sigma - expected).norm(), 1e-9 * expected.norm());
  EXPECT_NEAR(psi, mu * eps.squaredNorm() + 0.5 * lambda * eps.sum() * eps.sum(), 1e-12 * psi);
  EXPECT_LT(kirchhoff_von_mises<3>(m, F), m.yield_stress);

  // 2D plane strain: the 2×2 block of the same closed form.
  const Vec<2> s2(1.0003, 0.9999);
  Mat<2> F2 = s2.asDiagonal();
  double alpha2 = 0.0;
  EXPECT_EQ(j2_return_map<2>(m, F2, alpha2), 0.0);
  Mat<2> sigma2;
  elastic_response<2>(m, F2, sigma2, psi);
  const Vec<2> eps2 = s2.array().log().matrix();
  for (int i = 0; i < 2; ++i)
    EXPECT_NEAR(sigma2(i, i), (2.0 * mu * eps2[i] + lambda * eps2.sum()) / s2.prod(),
                1e-9 * std::abs(sigma2(i, i)));
  EXPECT_NEAR(sigma2(0, 1), 0.0, 1e-9);
}

template <int Dim>
void expect_on_yield_surface(const Mat<Dim>& F_trial, double alpha0) {
  const Material m = clay();
  Mat<Dim> F = F_trial;
  double alpha = alpha0;
  ASSERT_GT(kirchhoff_von_mises<Dim>(m, F), m.yield_stress_at(alpha0));  // beyond yield
  const double dgamma = j2_return_map<Dim>(m, F, alpha);
  EXPECT_GT(dgamma, 0.0);
  EXPECT_DOUBLE_EQ(alpha, alpha0 + std::sqrt(2.0 / 3.0) * dgamma);
  // On the softened yield surface at the new α, and isochoric.
  const double q = kirchhoff_von_mises<Dim>(m, F);
  EXPECT_NEAR(q, m.yield_stress_at(alpha), 1e-10 * m.yield_stress_at(alpha));
  EXPECT_NEAR(F.determinant(), F_trial.determinant(), 1e-13);
  // The pressure (volumetric log strain) is untouched by J2 flow.
  Mat<Dim> s0, s1;
  double psi;
  elastic_response<Dim>(m, F_trial, s0, psi);
  elastic_response<Dim>(m, F, s1, psi);
  EXPECT_NEAR(s1.trace(), s0.trace(), 1e-9 * std::abs(s0.trace()) + 1e-6);
  // A second map at the same state is elastic: the state is admissible.
  double alpha_again = alpha;
  Mat<Dim> F_again = F;
  EXPECT_LT(j2_return_map<Dim>(m, F_again, alpha_again), 1e-12);
}

TEST(HenckyJ2, ReturnMapLandsOnYieldSurfaceAndKeepsVolume) {
  expect_on_yield_surface<3>(Vec<3>(1.2, 1.0, 1.0).asDiagonal().toDenseMatrix(), 0.0);
  Mat<3> shear = Mat<3>::Identity();
  shear(0, 1) = 0.5;  // simple shear, rotated
  expect_on_yield_surface<3>(rotation<3>(0.3) * shear, 0.1);
  Mat<2> shear2 = Mat<2>::Identity();
  shear2(0, 1) = 0.4;
  expect_on_yield_surface<2>(shear2, 0.0);
  expect_on_yield_surface<2>(rotation<2>(-1.1) * Vec<2>(1.3, 0.9).asDiagonal(), 0.05);
}

TEST(HenckyJ2, SofteningFollowsTheExponentialLaw) {
  const Material m = clay(5.0);
  Mat<3> F = Mat<3>::Identity();
  double alpha = 0.0, previous_yield = m.yield_stress;
  // Repeated isochoric pure-shear increments, each well beyond yield.
  const Vec<3> increment(1.02, 1.0 / 1.02, 1.0);
  for (int k = 0; k < 60; ++k) {
    F = increment.asDiagonal() * F;
    const double alpha_before = alpha;
    const double dgamma = j2_return_map<3>(m, F, alpha);
    ASSERT_GT(dgamma, 0.0) << k;
    EXPECT_GT(alpha, alpha_before);
    const double expected = 2.45e3 + (40.82e3 - 2.45e3) * std::exp(-5.0 * alpha);
    EXPECT_NEAR(m.yield_stress_at(alpha), expected, 1e-9 * expected);
    EXPECT_LT(expected, previous_yield);
    EXPECT_NEAR(kirchhoff_von_mises<3>(m, F), expected, 1e-10 * expected) << k;
    previous_yield = expected;
  }
  EXPECT_GT(alpha, 1.0);
  EXPECT_LT(m.yield_stress_at(alpha) - 2.45e3, 0.01 * (40.82e3 - 2.45e3));
  // Without softening the yield stress stays at its peak (perfect plasticity).
  const Material perfect = clay(0.0);
  Mat<3> G = Vec<3>(1.3, 1.0 / 1.3, 1.0).asDiagonal();
  double a = 0.0;
  j2_return_map<3>(perfect, G, a);
  EXPECT_GT(a, 0.0);
  EXPECT_NEAR(kirchhoff_von_mises<3>(perfect, G), 40.82e3, 1e-10 * 40.82e3);
}

TEST(HenckyJ2, SmallStrainLimitIsLinearElasticity) {
  Material hencky = clay();
  Material linear = hencky;
  linear.model = MaterialModel::kLinearElastic;
  Mat<3> dir;
  dir << 0.7, 0.2, -0.1, 0.2, -0.4, 0.3, -0.1, 0.3, 0.5;  // symmetric: no rotation
  double previous = 0.0;
  for (double h : {1e-3, 1e-4}) {
    const Mat<3> F = Mat<3>::Identity() + h * dir;
    Mat<3> sh, sl;
    double psi;
    elastic_response<3>(hencky, F, sh, psi);
    elastic_response<3>(linear, F, sl, psi);
    const double error = (sh - sl).norm(), scale = 2.0 * hencky.mu() + 3.0 * hencky.lambda();
    EXPECT_LT(error, 10.0 * scale * h * h) << h;
    EXPECT_GT(error, 0.0);
    if (previous > 0.0) {
      EXPECT_NEAR(error / previous, 0.01, 0.002);  // O(strain²)
    }
    previous = error;
  }
}

std::string slope_error(const std::vector<std::string>& sets) {
  try {
    load_scene(kSlope, sets);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(HenckyJ2, BadParametersNameFileAndKey) {
  const std::string key = "bodies.0.material.";
  for (const auto& [set, name] : std::vector<std::pair<std::string, std::string>>{
           {key + "yield_stress=0", "yield_stress"},
           {key + "yield_stress=-5.0", "yield_stress"},
           {key + "residual_yield_stress=5.0e4", "residual_yield_stress"},
           {key + "residual_yield_stress=0", "residual_yield_stress"},
           {key + "softening=-1.0", "softening"},
           {key + "model=neo_hookean", "unknown key"},  // plasticity keys on an elastic model
           {key + "model=hencky", "model"}}) {
    const std::string m = slope_error({set});
    EXPECT_NE(m.find("slope.json"), std::string::npos) << set << ": " << m;
    EXPECT_NE(m.find(name == "unknown key" ? "unknown key '" + key : key + name), std::string::npos)
        << set << ": " << m;
  }
  EXPECT_EQ(slope_error({}), "");
}

TEST(Slope, SceneParsesAsPlaneStrainHenckyJ2) {
  const Scene scene = load_scene(kSlope);
  EXPECT_EQ(scene.dim, 2);
  ASSERT_EQ(scene.bodies.size(), 1u);
  EXPECT_EQ(scene.bodies[0].shape.type, "polygon");
  EXPECT_EQ(scene.bodies[0].material.model, MaterialModel::kHenckyJ2);
  EXPECT_LT(scene.bodies[0].material.residual_yield_stress, scene.bodies[0].material.yield_stress);
  EXPECT_GT(scene.bodies[0].material.softening, 0.0);
  EXPECT_LT(scene.gravity[1], 0.0);
  // A polygon is 2D only and needs a real area.
  EXPECT_NE(slope_error({"bodies.0.shape.points=[[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]"})
                .find("bodies.0.shape.points"),
            std::string::npos);
  EXPECT_NE(slope_error({"bodies.0.shape.points=[[0.0, 0.0], [1.0]]"}), "");
}

TEST(Slope, CoarseSlopeStartsToFailUnderGravity) {
  // Twice as coarse as the shipped scene and 0.3 s of its 2 s.
  const Scene scene = load_scene(
      kSlope, {"bodies.0.spacing=0.4", "background.element_size=0.8", "solver.end_time=0.3"});
  BuiltScene<2> built = build_scene<2>(scene);
  const Particles<2>& p0 = built.particles;
  ASSERT_GT(p0.size(), 100);
  MpmSolver<2> solver(std::move(built.background), built.materials, built.particles,
                      built.constraints, built.settings);
  solver.advance_to(scene.solver.end_time);
  const Particles<2>& p = solver.particles();
  double alpha_max = 0.0, y_min = 1e300, y_top_initial = 0.0, y_top = 0.0;
  int plastic = 0;
  for (int32_t i = 0; i < p.size(); ++i) {
    ASSERT_TRUE(p.x[i].allFinite() && p.v[i].allFinite() && p.F[i].allFinite()) << i;
    ASSERT_TRUE(std::isfinite(p.plastic_strain[i])) << i;
    EXPECT_GE(p.plastic_strain[i], 0.0);
    alpha_max = std::max(alpha_max, p.plastic_strain[i]);
    plastic += p.plastic_strain[i] > 0.0;
    y_min = std::min(y_min, p.x[i][1]);
    y_top_initial = std::max(y_top_initial, p0.x[i][1]);
    y_top = std::max(y_top, p.x[i][1]);
  }
  // Nothing sinks through the fixed base (y = 0). The base is imposed on grid nodes (wall nodes
  // fixed, ghosts mirrored), so a particle on the wall moves with the interpolated grid velocity,
  // zero only to interpolation accuracy: allow 1% of the element size.
  EXPECT_GE(y_min, -0.01 * scene.background.element_size);
  EXPECT_GT(alpha_max, 0.0);
  EXPECT_GT(plastic, 0);
  EXPECT_LT(y_top, y_top_initial + 1e-3);  // gravity: the crest settles, it does not rise
  std::printf(
      "coarse slope: %d particles, %d steps, %d yielded, max plastic strain %.3g, min y %.3g m\n",
      p.size(), static_cast<int>(solver.steps()), plastic, alpha_max, y_min);
}

TEST(Slope, FramesCarryPlasticStrain) {
  namespace fs = std::filesystem;
  const fs::path dir = bsms::testing::unique_temp_dir("slope") / "run";
  const Scene scene = load_scene(kSlope, {"bodies.0.spacing=0.4", "background.element_size=0.8",
                                          "solver.end_time=0.2", "output.frames=3"});
  const SimulationSummary s = simulate_scene(scene, dir.string(), false);
  H5File f((dir / "frames.h5").string(), H5File::Mode::kRead);
  EXPECT_EQ(f.shape("/frames/plastic_strain"), (Shape{3, static_cast<hsize_t>(s.particles)}));
  const auto alpha = f.read<float>("/frames/plastic_strain");
  for (int64_t i = 0; i < s.particles; ++i) EXPECT_EQ(alpha[i], 0.0f);  // frame 0: intact
  EXPECT_GT(*std::max_element(alpha.begin(), alpha.end()), 0.0f);
  fs::remove_all(dir);
  // Only the known fields are accepted.
  EXPECT_NE(slope_error({"output.fields=[\"plastic\"]"}).find("output.fields"), std::string::npos);
}

}  // namespace
}  // namespace bsms::mpm
