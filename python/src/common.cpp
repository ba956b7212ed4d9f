#include "common.hpp"

#include <omp.h>

#include "core/config.hpp"
#include "core/one_line.hpp"
#include "core/runtime.hpp"

namespace bsms::python {

namespace {
std::mutex* shared_mutex = nullptr;
}

std::mutex& library_mutex() {
  return *shared_mutex;
}

void share_library_mutex(py::module_& module) {
  // _core owns the lock and hands it to _torch through a capsule: each extension module has its
  // own copy of this file, and one lock must cover both.
  if (module.attr("__name__").cast<std::string>() == "bsms._core") {
    shared_mutex = new std::mutex;  // lives as long as the process (Python never unloads it)
    module.attr("_library_mutex") = py::capsule(shared_mutex, "bsms._library_mutex");
  } else {
    const py::capsule c = py::module_::import("bsms._core").attr("_library_mutex");
    shared_mutex = static_cast<std::mutex*>(c.get_pointer());
  }
}

ThreadScope::ThreadScope(int threads)
    : before_(omp_get_max_threads()), threads_(set_num_threads(threads)) {}

ThreadScope::~ThreadScope() {
  omp_set_num_threads(before_);
}

std::string shape_text(const py::array& array) {
  std::string text = "(";
  for (py::ssize_t d = 0; d < array.ndim(); ++d)
    text += (d > 0 ? ", " : "") + std::to_string(array.shape(d));
  return text + (array.ndim() == 1 ? ",)" : ")");
}

std::string truncate(const py::handle& value) {
  return truncate_for_message(py::str(value));
}

py::array checked_array(const py::handle& value, const std::string& what, char kind, int ndim_min,
                        int ndim_max) {
  py::array array = py::array::ensure(value);
  if (!array) {
    PyErr_Clear();
    throw InputError(what + ": expected an array, got " +
                     std::string(py::str(py::type::handle_of(value).attr("__name__"))));
  }
  const char k = array.dtype().kind();
  const bool integer = k == 'i' || k == 'u';
  if (kind == 'i' ? !integer : !(integer || k == 'f'))
    throw InputError(what + ": expected " +
                     (kind == 'i' ? std::string("an integer") : std::string("a floating-point")) +
                     " array, got dtype " + std::string(py::str(array.dtype())));
  if (array.ndim() < ndim_min || array.ndim() > ndim_max)
    throw InputError(what + ": expected " + std::to_string(ndim_min) +
                     (ndim_max > ndim_min ? " to " + std::to_string(ndim_max) : "") +
                     " dimensions, got shape " + shape_text(array));
  return array;
}

void register_errors(py::module_& module) {
  // One set of classes, whichever module raised: bsms.InputError is caught the same from both.
  // The classes live in bsms/_errors.py; held for the life of the process (never released, so
  // nothing is freed after the interpreter has gone).
  struct Classes {
    py::object input, numerical, io;
  };
  static Classes* classes = nullptr;
  if (classes == nullptr) {
    const py::module_ errors = py::module_::import("bsms._errors");
    classes = new Classes{errors.attr("InputError"), errors.attr("NumericalError"),
                          errors.attr("IoError")};
  }
  module.attr("InputError") = classes->input;
  module.attr("NumericalError") = classes->numerical;
  module.attr("IoError") = classes->io;
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const InputError& e) {
      PyErr_SetString(classes->input.ptr(), one_line(e.what()).c_str());
    } catch (const NumericalError& e) {
      PyErr_SetString(classes->numerical.ptr(), one_line(e.what()).c_str());
    } catch (const IoError& e) {
      PyErr_SetString(classes->io.ptr(), one_line(e.what()).c_str());
    } catch (const DistributedError& e) {
      PyErr_SetString(PyExc_RuntimeError, one_line(e.what()).c_str());
    }
  });
}

}  // namespace bsms::python
