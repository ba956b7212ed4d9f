// Shared by the Python extension modules (bsms._core, bsms._torch): NumPy arrays to and from the
// C++ types, bsms's errors as Python exceptions, and one lock around the library's work.
#pragma once

#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "core/error.hpp"

namespace bsms::python {

namespace py = pybind11;
// Paths arrive as str or any os.PathLike (pathlib.Path).
using Path = std::filesystem::path;

// Registers InputError (a ValueError), NumericalError (an ArithmeticError) and IoError (an
// OSError) in `module`, each carrying the message the CLI prints for the same failure (one
// line, without the "bsms: error: " prefix). The torch module shares the core module's classes.
void register_errors(py::module_& module);

// libhdf5 as Debian builds it is not thread-safe, and the solver and the OpenMP thread count are
// process-wide: every call into the library holds this lock. Long calls release the GIL while they
// hold it (run_unlocked), so other Python threads run meanwhile; a call waiting for the lock never
// holds the GIL, so a progress callback that takes the GIL cannot deadlock against it.
std::mutex& library_mutex();
// Called first by each module's init: bsms._core creates the lock, bsms._torch takes _core's.
void share_library_mutex(py::module_& module);

template <class F>
auto run_unlocked(F&& work) -> decltype(work()) {
  py::gil_scoped_release release;
  const std::lock_guard<std::mutex> lock(library_mutex());
  return work();
}

// The thread count of one call (0: every core), the caller's restored afterwards: OpenMP's count is
// process-wide, shared with a torch the caller uses in the same process.
class ThreadScope {
 public:
  explicit ThreadScope(int threads);
  ~ThreadScope();
  ThreadScope(const ThreadScope&) = delete;
  ThreadScope& operator=(const ThreadScope&) = delete;
  int threads() const { return threads_; }

 private:
  int before_ = 0, threads_ = 0;
};

// Array with the data of `values` (moved, no copy) and `shape`; the array owns it.
template <class T>
py::array_t<T> to_numpy(std::vector<T>&& values, const std::vector<py::ssize_t>& shape) {
  auto* owned = new std::vector<T>(std::move(values));
  py::capsule free_when_done(owned, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  return py::array_t<T>(shape, owned->data(), free_when_done);
}

// A read-only array over memory kept alive by `owner` (no copy).
template <class T>
py::array_t<T> view_numpy(const T* data, const std::vector<py::ssize_t>& shape, py::handle owner) {
  py::array_t<T> out(shape, data, owner);
  py::detail::array_proxy(out.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  return out;
}

// `value` as an array (anything numpy.asarray takes) of `kind` 'f' (floating point; integers are
// accepted and converted) or 'i' (integers only: float indices are refused, not truncated), with
// ndim_min..ndim_max dimensions. InputError naming `what`, the dtype or the shape otherwise.
py::array checked_array(const py::handle& value, const std::string& what, char kind, int ndim_min,
                        int ndim_max);

// A C-contiguous T copy of a checked array (no copy when it already is one).
template <class T>
py::array_t<T, py::array::c_style> as_contiguous(const py::array& array) {
  return py::array_t<T, py::array::c_style | py::array::forcecast>::ensure(array);
}

std::string shape_text(const py::array& array);  // "(3, 2)"
std::string truncate(const py::handle& value);   // str(value), cut for a message

}  // namespace bsms::python
