// Constitutive models. F is the deformation gradient [Dim, Dim]; stresses in Pa; energy density
// ψ in J/m³ of reference volume.
#pragma once

#include <string>

#include "data/mpm/background.hpp"

namespace bsms::mpm {

enum class MaterialModel { kLinearElastic, kFixedCorotated, kNeoHookean, kHenckyJ2 };
std::string to_string(MaterialModel model);
// "linear_elastic" | "fixed_corotated" | "neo_hookean" | "hencky_j2"; InputError naming `where`
// otherwise.
MaterialModel parse_material_model(const std::string& name, const std::string& where);

struct Material {
  MaterialModel model = MaterialModel::kLinearElastic;
  double youngs_modulus = 1.0;  // Pa, > 0
  double poisson_ratio = 0.0;   // in (-1, 0.5)
  double density = 1.0;         // kg/m³, > 0
  // hencky_j2 only: von Mises yield stress σ_y(α) = σ_r + (σ_0 − σ_r) exp(−ξ α), Pa, softening
  // with the equivalent plastic strain α (thesis 2.3.4: κ = (κ_p − κ_r) e^{−η ε_q^p} + κ_r).
  double yield_stress = 0.0;           // σ_0 (peak), Pa, > 0
  double residual_yield_stress = 0.0;  // σ_r, Pa, in (0, σ_0]
  double softening = 0.0;              // ξ, dimensionless, >= 0
  // Kelvin–Voigt viscosity η, Pa·s, >= 0 (any model): the Cauchy stress gains η (∇v + ∇vᵀ), so a
  // stiff body's vibrations die out while a rigid motion (∇v skew) keeps its energy. Stiff bodies
  // ring at frequencies far above a dataset's frame rate (rubber balls of 0.1 m: kHz against
  // 50 Hz frames); undamped, that ringing is aliased noise no model can predict.
  double viscosity = 0.0;
  double yield_stress_at(double alpha) const;
  double mu() const { return youngs_modulus / (2.0 * (1.0 + poisson_ratio)); }
  double lambda() const {
    return youngs_modulus * poisson_ratio / ((1.0 + poisson_ratio) * (1.0 - 2.0 * poisson_ratio));
  }
  // P-wave speed sqrt((λ + 2μ) / ρ), m/s.
  double wave_speed() const;
};

// Cauchy stress σ = P Fᵀ / J and strain energy density ψ(F). Linear elastic is the small-strain
// model in the reference frame (P = 2μ ε + λ tr ε I, ε = sym(F) − I): it reproduces the linear
// wave equation of the vibrating bar exactly but is not rotation invariant.
template <int Dim>
void elastic_response(const Material& material, const Mat<Dim>& F, Mat<Dim>& sigma, double& psi);

// Hencky (logarithmic-strain) elasticity, used by hencky_j2: with F = U Σ Vᵀ and ε = log Σ,
// τ = U (2μ ε + λ tr(ε) I) Uᵀ (Kirchhoff), σ = τ / J, ψ = μ |ε|² + λ/2 (tr ε)².
// 2D is plane strain: the 2×2 block with F_zz = 1 (ε_zz = 0 elastically).
template <int Dim>
void hencky_response(const Material& material, const Mat<Dim>& F, Mat<Dim>& sigma, double& psi);

// J2 return mapping of hencky_j2 in log-strain space. Convention: σ_y is a von Mises (uniaxial)
// stress, q = sqrt(3/2) |dev τ|, yield when |dev τ| > sqrt(2/3) σ_y(α); the deviator is taken
// over the Dim principal log strains, ε̂ = ε − tr(ε)/Dim (2D: in-plane deviator of the 2×2
// block). Plastic flow removes Δγ along ε̂/|ε̂| (isochoric: tr ε and det F are unchanged) and
// α grows by sqrt(2/3) Δγ (equivalent plastic strain). The softened yield stress is evaluated
// implicitly at the new α, so after the map |dev τ| = sqrt(2/3) σ_y(α_new). Updates F (the
// elastic deformation gradient) and alpha in place; returns Δγ (0 if elastic). Other models:
// no-op.
template <int Dim>
double j2_return_map(const Material& material, Mat<Dim>& F, double& alpha);

// von Mises equivalent stress of a Cauchy stress (plane-stress form in 2D), Pa.
template <int Dim>
double von_mises(const Mat<Dim>& sigma);

}  // namespace bsms::mpm
