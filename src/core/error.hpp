// Typed errors with context. The CLI maps InputError to one line on stderr and exit code 2,
// NumericalError (a solver step that failed) to exit code 3.
#pragma once

#include <stdexcept>
#include <string>

namespace bsms {

// Bad input: a missing or malformed file, an unknown key, an impossible parameter, NaN data.
// The message must name the file, key or value and say what is expected.
class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& what) : std::runtime_error(what) {}
};

// A numerical failure during a computation (NaN, inverted element, particle outside the mesh).
// The message names the step, the particle (or node) and the cause.
class NumericalError : public std::runtime_error {
 public:
  explicit NumericalError(const std::string& what) : std::runtime_error(what) {}
};

// An I/O failure that is not the user's fault in the input (e.g. disk full while writing).
class IoError : public std::runtime_error {
 public:
  explicit IoError(const std::string& what) : std::runtime_error(what) {}
};

}  // namespace bsms
