#include "data/mpm/material.hpp"

#include <Eigen/SVD>
#include <cmath>

#include "core/error.hpp"

namespace bsms::mpm {

std::string to_string(MaterialModel model) {
  switch (model) {
    case MaterialModel::kLinearElastic:
      return "linear_elastic";
    case MaterialModel::kFixedCorotated:
      return "fixed_corotated";
    case MaterialModel::kNeoHookean:
      return "neo_hookean";
    case MaterialModel::kHenckyJ2:
      return "hencky_j2";
  }
  return "unknown";
}

MaterialModel parse_material_model(const std::string& name, const std::string& where) {
  for (MaterialModel m : {MaterialModel::kLinearElastic, MaterialModel::kFixedCorotated,
                          MaterialModel::kNeoHookean, MaterialModel::kHenckyJ2})
    if (to_string(m) == name) return m;
  throw InputError(where + ": unknown material model '" + name +
                   "' (allowed: linear_elastic, fixed_corotated, neo_hookean, hencky_j2)");
}

double Material::yield_stress_at(double alpha) const {
  return residual_yield_stress +
         (yield_stress - residual_yield_stress) * std::exp(-softening * alpha);
}

double Material::wave_speed() const {
  return std::sqrt((lambda() + 2.0 * mu()) / density);
}

namespace {

template <int Dim>
Mat<Dim> rotation_of(const Mat<Dim>& F) {
  if constexpr (Dim == 2) {
    const double c = F(0, 0) + F(1, 1), s = F(1, 0) - F(0, 1);
    const double len = std::hypot(c, s);
    Mat<2> R;
    if (len < 1e-300) return Mat<2>::Identity();
    R << c / len, -s / len, s / len, c / len;
    return R;
  } else {
    Eigen::JacobiSVD<Mat<Dim>> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Mat<Dim> U = svd.matrixU(), V = svd.matrixV();
    if (U.determinant() < 0) U.col(Dim - 1) *= -1.0;
    if (V.determinant() < 0) V.col(Dim - 1) *= -1.0;
    return U * V.transpose();
  }
}

// F = U diag(s) Vᵀ. Reflections in U, V are harmless: every use is U f(s) Uᵀ or U g(s) Vᵀ.
template <int Dim>
void svd_of(const Mat<Dim>& F, Mat<Dim>& U, Vec<Dim>& s, Mat<Dim>& V) {
  Eigen::JacobiSVD<Mat<Dim>> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  U = svd.matrixU();
  V = svd.matrixV();
  s = svd.singularValues();
}

}  // namespace

template <int Dim>
void hencky_response(const Material& material, const Mat<Dim>& F, Mat<Dim>& sigma, double& psi) {
  const double mu = material.mu(), lambda = material.lambda();
  Mat<Dim> U, V;
  Vec<Dim> s;
  svd_of<Dim>(F, U, s, V);
  const Vec<Dim> eps = s.array().log().matrix();
  const double tr = eps.sum();
  const Vec<Dim> tau = 2.0 * mu * eps + Vec<Dim>::Constant(lambda * tr);
  psi = mu * eps.squaredNorm() + 0.5 * lambda * tr * tr;
  sigma = U * tau.asDiagonal() * U.transpose() / s.prod();
}

template <int Dim>
double j2_return_map(const Material& material, Mat<Dim>& F, double& alpha) {
  if (material.model != MaterialModel::kHenckyJ2) return 0.0;
  const double mu = material.mu();
  Mat<Dim> U, V;
  Vec<Dim> s;
  svd_of<Dim>(F, U, s, V);
  const Vec<Dim> eps = s.array().log().matrix();
  const Vec<Dim> dev = eps - Vec<Dim>::Constant(eps.sum() / Dim);
  const double dev_norm = dev.norm();
  // |dev τ| = 2μ |ε̂|; the yield surface in log strain is |ε̂| = r(α) = sqrt(2/3) σ_y(α) / (2μ).
  const double c = std::sqrt(2.0 / 3.0) / (2.0 * mu);
  const double k = std::sqrt(2.0 / 3.0);  // dα / dΔγ
  if (dev_norm <= c * material.yield_stress_at(alpha)) return 0.0;
  // g(Δγ) = |ε̂| − Δγ − c σ_y(α + k Δγ) = 0. σ_y is convex and decreasing, so g is concave with
  // g(0) > 0 and g(|ε̂|) ≤ −c σ_r < 0: one root in the bracket; Newton safeguarded by bisection.
  const double drop = material.yield_stress - material.residual_yield_stress;
  auto g = [&](double dg) { return dev_norm - dg - c * material.yield_stress_at(alpha + k * dg); };
  double lo = 0.0, hi = dev_norm, dg = 0.0;
  for (int it = 0; it < 100; ++it) {
    const double val = g(dg);
    if (val > 0.0) {
      lo = dg;
    } else {
      hi = dg;
    }
    if (std::abs(val) <= 1e-15 * dev_norm || hi - lo <= 1e-16 * dev_norm) break;
    const double slope =
        -1.0 + c * k * material.softening * drop * std::exp(-material.softening * (alpha + k * dg));
    double next = slope < 0.0 ? dg - val / slope : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    dg = next;
  }
  const Vec<Dim> eps_new = eps - dg / dev_norm * dev;
  F = U * eps_new.array().exp().matrix().asDiagonal() * V.transpose();
  alpha += k * dg;
  return dg;
}

template <int Dim>
void elastic_response(const Material& material, const Mat<Dim>& F, Mat<Dim>& sigma, double& psi) {
  const double mu = material.mu(), lambda = material.lambda();
  const double J = F.determinant();
  const Mat<Dim> I = Mat<Dim>::Identity();
  Mat<Dim> P = Mat<Dim>::Zero();
  psi = 0.0;
  switch (material.model) {
    case MaterialModel::kLinearElastic: {
      const Mat<Dim> eps = 0.5 * (F + F.transpose()) - I;
      const double tr = eps.trace();
      P = 2.0 * mu * eps + lambda * tr * I;
      psi = mu * eps.squaredNorm() + 0.5 * lambda * tr * tr;
      break;
    }
    case MaterialModel::kFixedCorotated: {
      const Mat<Dim> R = rotation_of<Dim>(F);
      const Mat<Dim> FinvT = F.inverse().transpose();
      P = 2.0 * mu * (F - R) + lambda * (J - 1.0) * J * FinvT;
      psi = mu * (F - R).squaredNorm() + 0.5 * lambda * (J - 1.0) * (J - 1.0);
      break;
    }
    case MaterialModel::kNeoHookean: {
      const Mat<Dim> FinvT = F.inverse().transpose();
      const double logJ = std::log(J);
      P = mu * (F - FinvT) + lambda * logJ * FinvT;
      psi = 0.5 * mu * (F.squaredNorm() - Dim) - mu * logJ + 0.5 * lambda * logJ * logJ;
      break;
    }
    case MaterialModel::kHenckyJ2:
      hencky_response<Dim>(material, F, sigma, psi);
      return;
  }
  sigma = P * F.transpose() / J;
}

template <int Dim>
double von_mises(const Mat<Dim>& s) {
  if constexpr (Dim == 2) {
    return std::sqrt(std::max(
        0.0, s(0, 0) * s(0, 0) - s(0, 0) * s(1, 1) + s(1, 1) * s(1, 1) + 3.0 * s(0, 1) * s(1, 0)));
  } else {
    const Mat<Dim> dev = s - s.trace() / 3.0 * Mat<Dim>::Identity();
    return std::sqrt(1.5 * dev.squaredNorm());
  }
}

template void elastic_response<2>(const Material&, const Mat<2>&, Mat<2>&, double&);
template void elastic_response<3>(const Material&, const Mat<3>&, Mat<3>&, double&);
template void hencky_response<2>(const Material&, const Mat<2>&, Mat<2>&, double&);
template void hencky_response<3>(const Material&, const Mat<3>&, Mat<3>&, double&);
template double j2_return_map<2>(const Material&, Mat<2>&, double&);
template double j2_return_map<3>(const Material&, Mat<3>&, double&);
template double von_mises<2>(const Mat<2>&);
template double von_mises<3>(const Mat<3>&);

}  // namespace bsms::mpm
