// Transfer kernels w_ip and gradients ∇w_ip between particles and background nodes.
//
// UMLS (thesis §2.1.3): the particle's simplex gives N⁰ (its vertices, barycentric B) and N¹ (N⁰
// plus their mesh neighbours). Sample weights d_vp = N(|x_v − x_p| / h) η_vp, where N is the
// quadratic B-spline (support 1.5) applied to the *radial* distance (rotation invariant, C¹
// because N'(0) = 0 and N is C¹ at 0.5 and 1.5), h the element size unit of BackgroundMesh (the
// smallest unit keeping every cell vertex inside the support, see background.cpp), and
// η_vp = Σ_{n∈N⁰} B_n A_vn with self loops (η = 1 on N⁰). Linear-basis MLS then gives
// [w, ∇w] = M⁻¹ Qᵀ D with M = Qᵀ D Q (fixed-size, no heap allocation per particle).
// For comparison: UMLS without η, linear FEM shape functions, and the tensor-product quadratic
// B-spline on a regular lattice (the classic MPM reference).
#pragma once

#include <cmath>
#include <string>

#include "data/mpm/background.hpp"

namespace bsms::mpm {

enum class KernelType { kUmls, kUmlsNoEta, kLinearFem, kBspline };
std::string to_string(KernelType type);
// "umls" | "umls_no_eta" | "linear_fem" | "bspline"; InputError naming `where` otherwise.
KernelType parse_kernel(const std::string& name, const std::string& where);

// Quadratic B-spline N(q) for q >= 0 (support 1.5) and its derivative dN/dq.
inline double quadratic_bspline(double q) {
  if (q < 0.5) return 0.75 - q * q;
  if (q < 1.5) return 0.5 * (1.5 - q) * (1.5 - q);
  return 0.0;
}

template <int Dim>
struct KernelEntry {
  int32_t node;
  double w;       // dimensionless
  Vec<Dim> grad;  // 1/m
};

// Result codes of TransferKernel::evaluate besides an entry count.
constexpr int kOutsideMesh = -1;
constexpr int kSingularMoment = -2;

template <int Dim>
class TransferKernel {
 public:
  TransferKernel(KernelType type, const BackgroundMesh<Dim>& background);

  KernelType type() const { return type_; }
  // Upper bound on the entries one evaluation writes.
  int max_entries() const { return max_entries_; }
  // Node spacing that limits the explicit time step (m).
  double cfl_spacing() const;

  // Weights and gradients at x (m). `cell` is the walk hint, updated to the containing cell.
  // Returns the number of entries written to `out` (<= max_entries()), kOutsideMesh, or
  // kSingularMoment when the MLS moment matrix is singular (degenerate samples).
  int evaluate(const Vec<Dim>& x, int32_t& cell, KernelEntry<Dim>* out) const {
    if (type_ == KernelType::kUmls || type_ == KernelType::kUmlsNoEta ||
        type_ == KernelType::kLinearFem) {
      Eigen::Matrix<double, Dim + 1, 1> bary;
      const int32_t c = bg_.locate(x, cell, bary);
      if (c < 0) return kOutsideMesh;
      cell = c;
      return evaluate_in_cell(x, c, bary, out);
    }
    return evaluate_bspline(x, out);
  }

  // As evaluate, for a simplicial background where x is already located in `cell` with
  // barycentric coordinates `bary` (the solver locates once per step).
  int evaluate_in_cell(const Vec<Dim>& x, int32_t cell,
                       const Eigen::Matrix<double, Dim + 1, 1>& bary, KernelEntry<Dim>* out) const {
    switch (type_) {
      case KernelType::kUmls:
        return evaluate_umls<true>(x, cell, bary, out);
      case KernelType::kUmlsNoEta:
        return evaluate_umls<false>(x, cell, bary, out);
      case KernelType::kLinearFem:
        return evaluate_fem(cell, bary, out);
      case KernelType::kBspline:
        return evaluate_bspline(x, out);
    }
    return kOutsideMesh;
  }

 private:
  template <bool UseEta>
  int evaluate_umls(const Vec<Dim>& x, int32_t c, const Eigen::Matrix<double, Dim + 1, 1>& bary,
                    KernelEntry<Dim>* out) const {
    using Mat1 = Eigen::Matrix<double, Dim + 1, Dim + 1>;
    const double inv_h = 1.0 / bg_.h;
    // Scalar accumulation of the symmetric moment matrix keeps everything in registers (Eigen
    // temporaries of size Dim + 1 went through the stack and stalled store forwarding).
    double m[Dim + 1][Dim + 1] = {};
    int n = 0;
    for (int32_t s = bg_.stencil_offsets[c]; s < bg_.stencil_offsets[c + 1]; ++s) {
      const int32_t v = bg_.stencil_nodes[s];
      double r[Dim];
      double q2 = 0.0;
      for (int a = 0; a < Dim; ++a) {
        r[a] = (bg_.points[v][a] - x[a]) * inv_h;  // scaled by 1/h for conditioning
        q2 += r[a] * r[a];
      }
      if (q2 >= 2.25) continue;  // support 1.5 h
      double d = quadratic_bspline(std::sqrt(q2));
      if constexpr (UseEta) {
        const unsigned mask = bg_.stencil_mask[s];
        double eta = 0.0;
        for (int k = 0; k <= Dim; ++k)
          if (mask & (1u << k)) eta += bary[k];
        d *= eta;
        if (!(d > 0.0)) continue;
      }
      m[0][0] += d;
      for (int a = 0; a < Dim; ++a) {
        const double dr = d * r[a];
        m[0][a + 1] += dr;
        for (int b = a; b < Dim; ++b) m[a + 1][b + 1] += dr * r[b];
      }
      out[n].node = v;
      out[n].w = d;
      for (int a = 0; a < Dim; ++a) out[n].grad[a] = r[a];
      ++n;
    }
    Mat1 moment;
    for (int a = 0; a <= Dim; ++a)
      for (int b = a; b <= Dim; ++b) moment(a, b) = moment(b, a) = m[a][b];
    Mat1 inverse;
    double det;
    bool invertible;
    moment.computeInverseAndDetWithCheck(inverse, det, invertible, 0.0);
    double scale = moment.trace();
    for (int k = 0; k < Dim; ++k) scale *= moment.trace();
    if (!invertible || !(std::abs(det) > 1e-14 * scale)) return kSingularMoment;
    double inv[Dim + 1][Dim + 1];
    for (int a = 0; a <= Dim; ++a)
      for (int b = 0; b <= Dim; ++b) inv[a][b] = inverse(a, b);
    for (int i = 0; i < n; ++i) {
      const double d = out[i].w;
      double r[Dim];
      for (int a = 0; a < Dim; ++a) r[a] = out[i].grad[a];
      double coeff[Dim + 1];
      for (int a = 0; a <= Dim; ++a) {
        double sum = inv[a][0];
        for (int b = 0; b < Dim; ++b) sum += inv[a][b + 1] * r[b];
        coeff[a] = sum * d;
      }
      out[i].w = coeff[0];
      for (int a = 0; a < Dim; ++a) out[i].grad[a] = coeff[a + 1] * inv_h;
    }
    return n;
  }

  int evaluate_fem(int32_t c, const Eigen::Matrix<double, Dim + 1, 1>& bary,
                   KernelEntry<Dim>* out) const {
    const Mat<Dim>& inv = bg_.inv_jacobian[c];
    out[0].grad = -inv.colwise().sum().transpose();
    for (int k = 0; k <= Dim; ++k) {
      out[k].node = bg_.cells[c][k];
      out[k].w = bary[k];
      if (k > 0) out[k].grad = inv.row(k - 1).transpose();
    }
    return Dim + 1;
  }

  int evaluate_bspline(const Vec<Dim>& x, KernelEntry<Dim>* out) const {
    const RegularGrid<Dim>& g = *bg_.grid;
    const double inv_dx = 1.0 / g.dx;
    std::array<int32_t, Dim> base;
    double w[Dim][3], dw[Dim][3];
    for (int a = 0; a < Dim; ++a) {
      const double xi = (x[a] - g.origin[a]) * inv_dx;
      const double b = std::floor(xi - 0.5);
      if (!(b >= 0.0 && b + 2.0 < g.counts[a])) return kOutsideMesh;
      base[a] = static_cast<int32_t>(b);
      const double f = xi - b;  // in [0.5, 1.5)
      w[a][0] = 0.5 * (1.5 - f) * (1.5 - f);
      w[a][1] = 0.75 - (f - 1.0) * (f - 1.0);
      w[a][2] = 0.5 * (f - 0.5) * (f - 0.5);
      dw[a][0] = (f - 1.5) * inv_dx;
      dw[a][1] = -2.0 * (f - 1.0) * inv_dx;
      dw[a][2] = (f - 0.5) * inv_dx;
    }
    int n = 0;
    std::array<int32_t, Dim> o{};
    while (true) {
      std::array<int32_t, Dim> ijk;
      double weight = 1.0;
      for (int a = 0; a < Dim; ++a) {
        ijk[a] = base[a] + o[a];
        weight *= w[a][o[a]];
      }
      out[n].node = g.index(ijk);
      out[n].w = weight;
      for (int a = 0; a < Dim; ++a) {
        double gradient = dw[a][o[a]];
        for (int b = 0; b < Dim; ++b)
          if (b != a) gradient *= w[b][o[b]];
        out[n].grad[a] = gradient;
      }
      ++n;
      int a = 0;
      while (a < Dim && ++o[a] > 2) o[a] = 0, ++a;
      if (a == Dim) break;
    }
    return n;
  }

  KernelType type_;
  const BackgroundMesh<Dim>& bg_;
  int max_entries_ = 0;
};

}  // namespace bsms::mpm
