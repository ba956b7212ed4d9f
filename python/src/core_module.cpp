// bsms._core: the parts of bsms without LibTorch (preprocessor, datasets, solver, generator).
// bsms/__init__.py is the public face; docs/python.md the guide.
#include "common.hpp"
#include "core/runtime.hpp"

namespace bsms::python {
void bind_preprocess(py::module_& m);
void bind_data(py::module_& m);
void bind_solver(py::module_& m);
}  // namespace bsms::python

PYBIND11_MODULE(_core, m) {
  namespace bp = bsms::python;
  m.doc() = "bsms without LibTorch: preprocessing, datasets, the UMLS-MPM solver";
  bp::share_library_mutex(m);
  bp::register_errors(m);
  m.def("hardware_threads", &bsms::hardware_threads);
  bp::bind_preprocess(m);
  bp::bind_data(m);
  bp::bind_solver(m);
}
