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
  }
  return "unknown";
}

MaterialModel parse_material_model(const std::string& name, const std::string& where) {
  for (MaterialModel m :
       {MaterialModel::kLinearElastic, MaterialModel::kFixedCorotated, MaterialModel::kNeoHookean})
    if (to_string(m) == name) return m;
  throw InputError(where + ": unknown material model '" + name +
                   "' (allowed: linear_elastic, fixed_corotated, neo_hookean)");
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

}  // namespace

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
template double von_mises<2>(const Mat<2>&);
template double von_mises<3>(const Mat<3>&);

}  // namespace bsms::mpm
