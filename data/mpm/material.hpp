// Constitutive models. F is the deformation gradient [Dim, Dim]; stresses in Pa; energy density
// ψ in J/m³ of reference volume.
#pragma once

#include <string>

#include "data/mpm/background.hpp"

namespace bsms::mpm {

enum class MaterialModel { kLinearElastic, kFixedCorotated, kNeoHookean };
std::string to_string(MaterialModel model);
// "linear_elastic" | "fixed_corotated" | "neo_hookean"; InputError naming `where` otherwise.
MaterialModel parse_material_model(const std::string& name, const std::string& where);

struct Material {
  MaterialModel model = MaterialModel::kLinearElastic;
  double youngs_modulus = 1.0;  // Pa, > 0
  double poisson_ratio = 0.0;   // in (-1, 0.5)
  double density = 1.0;         // kg/m³, > 0
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

// von Mises equivalent stress of a Cauchy stress (plane-stress form in 2D), Pa.
template <int Dim>
double von_mises(const Mat<Dim>& sigma);

}  // namespace bsms::mpm
