#include "data/mpm/kernel.hpp"

#include "core/error.hpp"

namespace bsms::mpm {

std::string to_string(KernelType type) {
  switch (type) {
    case KernelType::kUmls:
      return "umls";
    case KernelType::kUmlsNoEta:
      return "umls_no_eta";
    case KernelType::kLinearFem:
      return "linear_fem";
    case KernelType::kBspline:
      return "bspline";
  }
  return "unknown";
}

KernelType parse_kernel(const std::string& name, const std::string& where) {
  for (KernelType t :
       {KernelType::kUmls, KernelType::kUmlsNoEta, KernelType::kLinearFem, KernelType::kBspline})
    if (to_string(t) == name) return t;
  throw InputError(where + ": unknown kernel '" + name +
                   "' (allowed: umls, umls_no_eta, linear_fem, bspline)");
}

template <int Dim>
TransferKernel<Dim>::TransferKernel(KernelType type, const BackgroundMesh<Dim>& background)
    : type_(type), bg_(background) {
  if (type == KernelType::kBspline) {
    if (!background.grid) throw InputError("kernel bspline needs a regular lattice background");
    int n = 1;
    for (int a = 0; a < Dim; ++a) n *= 3;
    max_entries_ = n;
  } else {
    if (background.grid)
      throw InputError("kernel " + to_string(type) + " needs a simplicial background mesh");
    max_entries_ = type == KernelType::kLinearFem ? Dim + 1 : background.max_stencil;
  }
}

template <int Dim>
double TransferKernel<Dim>::cfl_spacing() const {
  switch (type_) {
    case KernelType::kLinearFem:
      return bg_.min_height;
    case KernelType::kBspline:
      return bg_.grid->dx;
    default:
      return bg_.mean_edge;
  }
}

template class TransferKernel<1>;
template class TransferKernel<2>;
template class TransferKernel<3>;

}  // namespace bsms::mpm
